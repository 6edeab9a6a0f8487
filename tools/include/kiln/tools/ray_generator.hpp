// Reproducible ray sets for `kiln rays`, the tests and the benchmarks: the same seed gives the
// same rays on every machine (SplitMix64, explicit float conversion, no std distributions).
#pragma once

#include <concepts>
#include <cstdint>
#include <span>
#include <vector>

#include "kiln/formats/geometry.hpp"
#include "kiln/runtime/capabilities.hpp"
#include "kiln/runtime/ray_structure.hpp"

namespace kiln {

enum class RayKind { kPrimary, kDiffuse, kShadow };

/// Closest triangle hits of single rays from a registry view's RayQueries (its Hit-sized
/// records: a triangle structure), or from any concrete triangle ray view, without a virtual
/// call. Borrows the view.
class ClosestHits {
 public:
  ClosestHits(const RayQueries& rays)
      : view_(&rays), closest_([](const void* view, const Ray& ray) {
          return static_cast<const RayQueries*>(view)->closest(ray);
        }) {}
  template <RayStructure View>
  ClosestHits(const View& view)
      : view_(&view), closest_([](const void* v, const Ray& ray) {
          return static_cast<const View*>(v)->intersect(ray);
        }) {
    static_assert(std::same_as<typename View::HitType, Hit>, "a triangle ray structure");
  }
  Hit operator()(const Ray& ray) const { return closest_(view_, ray); }

 private:
  const void* view_;
  Hit (*closest_)(const void*, const Ray&);
};

struct RayScene {
  ClosestHits closest;  // finds primary hits for diffuse and shadow rays (triangle ids)
  std::span<const format::Float3> positions;
  std::span<const format::Triangle> triangles;
  format::Float3 bounds_min, bounds_max;
};

/// A pinhole camera for primary rays (as `kiln render --camera` takes one): eye, the point it
/// looks at, vertical field of view in degrees (0 < fov < 180; eye apart from target).
struct RayCamera {
  format::Float3 eye, target;
  float fov_degrees;
};

// Primary: a pinhole camera framing the bounds. Diffuse: cosine-weighted bounces from primary
// hits. Shadow: from primary hits to a point light above the scene. Throws std::runtime_error
// when too few primary rays hit the scene to make diffuse or shadow rays.
std::vector<Ray> generate_rays(const RayScene& scene, RayKind kind, std::size_t count,
                               std::uint64_t seed, unsigned threads);
// The same from `camera` instead of the camera framing the bounds (an interior view).
std::vector<Ray> generate_rays(const RayScene& scene, const RayCamera& camera, RayKind kind,
                               std::size_t count, std::uint64_t seed, unsigned threads);

}  // namespace kiln
