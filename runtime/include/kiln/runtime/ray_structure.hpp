// The view contract every ray structure meets, and the one batch tracer over any of them.
#pragma once

#include <concepts>
#include <span>

#include "kiln/runtime/parallel.hpp"
#include "kiln/runtime/ray.hpp"

namespace kiln {

/// A ray structure's view: closest hit, first hit found, occlusion and a counted closest hit,
/// all on (ray.tmin, ray.tmax), all const and thread-safe. HitType is Hit or VoxelHit.
template <class V>
concept RayStructure = requires(const V& view, const Ray& ray, Cost& cost) {
  typename V::HitType;
  { view.intersect(ray) } -> std::same_as<typename V::HitType>;
  { view.intersect_any(ray) } -> std::same_as<typename V::HitType>;
  { view.occluded(ray) } -> std::same_as<bool>;
  { view.intersect_counting(ray, cost) } -> std::same_as<typename V::HitType>;
};

/// Closest hits (or, with `any_hit`, the first hit found) for many rays on up to `threads`
/// threads (0 = all cores). Each ray writes its own slot: results never depend on the count.
template <RayStructure V>
void trace_rays(const V& view, std::span<const Ray> rays, std::span<typename V::HitType> hits,
                bool any_hit, unsigned threads) {
  parallel_for_batched(rays.size(), kRaysPerTask, threads, [&](std::size_t i) {
    hits[i] = any_hit ? view.intersect_any(rays[i]) : view.intersect(rays[i]);
  });
}

}  // namespace kiln
