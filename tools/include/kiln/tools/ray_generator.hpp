// Reproducible ray sets for `kiln rays`, the tests and the benchmarks: the same seed gives the
// same rays on every machine (SplitMix64, explicit float conversion, no std distributions).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "kiln/formats/geometry.hpp"
#include "kiln/runtime/bvh.hpp"

namespace kiln {

enum class RayKind { kPrimary, kDiffuse, kShadow };

struct RayScene {
  const BvhView& bvh;  // used to find primary hits for diffuse and shadow rays
  std::span<const format::Float3> positions;
  std::span<const format::Triangle> triangles;
  format::Float3 bounds_min, bounds_max;
};

// Primary: a pinhole camera framing the bounds. Diffuse: cosine-weighted bounces from primary
// hits. Shadow: from primary hits to a point light above the scene. Throws std::runtime_error
// when too few primary rays hit the scene to make diffuse or shadow rays.
std::vector<Ray> generate_rays(const RayScene& scene, RayKind kind, std::size_t count,
                               std::uint64_t seed, unsigned threads);

}  // namespace kiln
