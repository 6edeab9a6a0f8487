// Front-to-back k-d tree traversal (Havran's TA_B recursive scheme as pbrt-v3 writes it) with a
// fixed stack. A leaf's triangles are tested against the whole ray, not just the cell, and the
// walk stops once the best hit lies before the cell's exit; so a triangle spanning cells is never
// missed, and plane distances are padded by their rounding error so no cell the ray touches is
// skipped.
#include <algorithm>
#include <cmath>

#include "kiln/runtime/kdtree.hpp"
#include "kiln/runtime/watertight.hpp"
#include "ray_box.hpp"

namespace kiln {

namespace {

constexpr float kNearScale = 2.0f - kFarScale;

template <bool kAnyHit, bool kCount>
Hit traverse(const KdTreeView& tree, const Ray& ray, Cost* cost) {
  const auto nodes = tree.nodes();
  const auto prim_ids = tree.prim_ids();
  const auto triangles = tree.triangles();
  const BoxRay box_ray = prepare_box_ray(ray);
  float tmin = ray.tmin, tmax = ray.tmax;
  const format::Box3f& b = tree.bounds();
  const float lo[3] = {b.min.x, b.min.y, b.min.z}, hi[3] = {b.max.x, b.max.y, b.max.z};
  if (!clip_to_box(lo, hi, box_ray, tmin, tmax)) return Hit{};
  const WatertightRay tri_ray = prepare_watertight(ray);
  const float dir[3] = {ray.dir.x, ray.dir.y, ray.dir.z};
  Hit hit;
  hit.t = ray.tmax;
  struct Entry {
    std::uint32_t node;
    float tmin, tmax;
  };
  Entry stack[format::kKdMaxDepth];
  std::uint32_t top = 0;
  std::uint32_t current = 0;
  for (;;) {
    const format::KdNode n = nodes[current];
    if constexpr (kCount) cost->nodes += 1;
    if (!n.is_leaf()) {
      const std::uint32_t a = n.axis();
      const float split = n.split();
      const std::uint32_t below = current + 1, above = n.above_child();
      if (dir[a] == 0.0f) {
        // Parallel to the plane: stays on the origin's side, or in both when on the plane.
        const float org = box_ray.org[a];
        if (org == split) stack[top++] = {above, tmin, tmax};
        current = org <= split ? below : above;
        continue;
      }
      const std::uint32_t first = dir[a] > 0.0f ? below : above;
      const std::uint32_t second = dir[a] > 0.0f ? above : below;
      const float t = (split - box_ray.org[a]) * box_ray.inv_dir[a];
      const float t_lo = t < 0.0f ? t * kFarScale : t * kNearScale;
      const float t_hi = t < 0.0f ? t * kNearScale : t * kFarScale;
      const bool visit_first = tmin <= t_hi;
      const bool visit_second = t_lo <= tmax;
      if (visit_first && visit_second) {
        stack[top++] = {second, std::max(tmin, t_lo), tmax};
        current = first;
        tmax = std::min(tmax, t_hi);
        continue;
      }
      if (visit_first) {
        current = first;
        continue;
      }
      if (visit_second) {
        current = second;
        continue;
      }
    } else {
      const std::uint32_t begin = n.first_reference(), end = begin + n.reference_count();
      for (std::uint32_t i = begin; i < end; ++i) {
        if constexpr (kCount) cost->tests += 1;
        const std::uint32_t prim = prim_ids[i];
        const format::RayTriangle& tri = triangles[prim];
        float t, u, v;
        if (intersect_watertight(tri_ray, tri.v0, tri.v1, tri.v2, ray.tmin, hit.t, t, u, v)) {
          hit = {t, prim, u, v};
          if constexpr (kAnyHit) return hit;
        }
      }
      // Nothing in a later cell can be closer than a hit inside this one.
      if (hit.prim != kNoHit && hit.t <= tmax) return hit;
    }
    // Pop the next cell along the ray; stop once cells start beyond the best hit.
    if (top == 0) break;
    --top;
    if (stack[top].tmin > hit.t) break;
    current = stack[top].node;
    tmin = stack[top].tmin;
    tmax = stack[top].tmax;
  }
  if (hit.prim == kNoHit) return Hit{};
  return hit;
}

}  // namespace

Hit KdTreeView::intersect(const Ray& ray) const {
  return traverse<false, false>(*this, ray, nullptr);
}

Hit KdTreeView::intersect_counting(const Ray& ray, Cost& cost) const {
  return traverse<false, true>(*this, ray, &cost);
}

Hit KdTreeView::intersect_any(const Ray& ray) const {
  return traverse<true, false>(*this, ray, nullptr);
}

bool KdTreeView::occluded(const Ray& ray) const {
  return traverse<true, false>(*this, ray, nullptr).hit();
}

}  // namespace kiln
