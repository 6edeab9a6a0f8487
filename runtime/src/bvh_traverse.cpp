// Ordered depth-first traversal (nearer child first, by box entry distance) with a fixed stack;
// BvhView's constructor guarantees the stack suffices.
#include <algorithm>
#include <limits>

#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/watertight.hpp"
#include "ray_box.hpp"

namespace kiln {

namespace {

// Both children's boxes are tested at their parent: the nearer is visited first, the farther
// is pushed with its entry distance and skipped on pop if a closer hit has been found since.
template <bool kAnyHit, bool kCount>
Hit traverse(const BvhView& bvh, const Ray& ray, Cost* cost) {
  constexpr float kMiss = std::numeric_limits<float>::infinity();
  const auto nodes = bvh.nodes();
  const auto triangles = bvh.triangles();
  const BoxRay box_ray = prepare_box_ray(ray);
  const WatertightRay tri_ray = prepare_watertight(ray);
  Hit hit;
  hit.t = ray.tmax;
  std::uint32_t best_ref = kNoHit;
  struct Entry {
    std::uint32_t node;
    float t;
  };
  Entry stack[format::kBvhMaxDepth];
  std::uint32_t top = 0;
  if constexpr (kCount) cost->nodes += 1;
  if (enter_box(nodes[0], box_ray, ray.tmin, hit.t) == kMiss) return Hit{};
  std::uint32_t current = 0;
  for (;;) {
    const format::BvhNode& n = nodes[current];
    if (n.count == 0) {
      const std::uint32_t first = current + 1, second = n.offset;
      const float t_first = enter_box(nodes[first], box_ray, ray.tmin, hit.t);
      const float t_second = enter_box(nodes[second], box_ray, ray.tmin, hit.t);
      if constexpr (kCount) cost->nodes += 2;
      if (t_first != kMiss && t_second != kMiss) {
        const bool first_nearer = t_first <= t_second;
        stack[top++] = first_nearer ? Entry{second, t_second} : Entry{first, t_first};
        current = first_nearer ? first : second;
        continue;
      }
      if (t_first != kMiss) {
        current = first;
        continue;
      }
      if (t_second != kMiss) {
        current = second;
        continue;
      }
    } else {
      for (std::uint32_t i = n.offset, end = n.offset + n.count; i < end; ++i) {
        if constexpr (kCount) cost->tests += 1;
        const format::RayTriangle& tri = triangles[i];
        float t, u, v;
        if (intersect_watertight(tri_ray, tri.v0, tri.v1, tri.v2, ray.tmin, hit.t, t, u, v)) {
          hit.t = t;
          hit.u = u;
          hit.v = v;
          best_ref = i;
          if constexpr (kAnyHit) {
            hit.prim = bvh.prim_ids()[i];
            return hit;
          }
        }
      }
    }
    // Pop the next subtree that can still hold a closer hit.
    do {
      if (top == 0) {
        if (best_ref == kNoHit) return Hit{};
        hit.prim = bvh.prim_ids()[best_ref];
        return hit;
      }
      --top;
    } while (stack[top].t > hit.t);
    current = stack[top].node;
  }
}

}  // namespace

Hit BvhView::intersect(const Ray& ray) const {
  return traverse<false, false>(*this, ray, nullptr);
}

Hit BvhView::intersect_counting(const Ray& ray, Cost& cost) const {
  return traverse<false, true>(*this, ray, &cost);
}

Hit BvhView::intersect_any(const Ray& ray) const {
  return traverse<true, false>(*this, ray, nullptr);
}

bool BvhView::occluded(const Ray& ray) const {
  return traverse<true, false>(*this, ray, nullptr).hit();
}

}  // namespace kiln
