// Ordered depth-first traversal (pbrt-style: the child on the near side of the split axis
// first) with a fixed stack; BvhView's constructor guarantees the stack suffices.
#include <algorithm>
#include <cmath>
#include <limits>

#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/parallel.hpp"
#include "kiln/runtime/watertight.hpp"

namespace kiln {

namespace {

// Slab test made conservative (pbrt-v4's 1 + 2 gamma(3) on the far distance) so rounding never
// culls a box the ray actually touches: watertightness needs the boxes to be watertight too.
constexpr float kFarScale = 1.0f + 2.0f * (3.0f * 0x1p-24f) / (1.0f - 3.0f * 0x1p-24f);

struct BoxRay {
  float org[3];
  float inv_dir[3];
  int negative[3];
};

BoxRay prepare_box_ray(const Ray& ray) {
  BoxRay b{};
  const float dir[3] = {ray.dir.x, ray.dir.y, ray.dir.z};
  const float org[3] = {ray.org.x, ray.org.y, ray.org.z};
  for (int a = 0; a < 3; ++a) {
    b.org[a] = org[a];
    b.inv_dir[a] = 1.0f / dir[a];  // +-inf for zero components: the slab test handles it
    b.negative[a] = b.inv_dir[a] < 0.0f;
  }
  return b;
}

inline bool hits_box(const format::BvhNode& n, const BoxRay& r, float tmin, float tmax) {
  for (int a = 0; a < 3; ++a) {
    const float lo = r.negative[a] ? n.max[a] : n.min[a];
    const float hi = r.negative[a] ? n.min[a] : n.max[a];
    float t0 = (lo - r.org[a]) * r.inv_dir[a];
    float t1 = (hi - r.org[a]) * r.inv_dir[a];
    // 0 * inf is NaN when the origin lies on a slab plane of a parallel axis: treat as inside.
    if (std::isnan(t0)) t0 = -std::numeric_limits<float>::infinity();
    if (std::isnan(t1)) t1 = std::numeric_limits<float>::infinity();
    t1 *= kFarScale;
    tmin = t0 > tmin ? t0 : tmin;
    tmax = t1 < tmax ? t1 : tmax;
    if (tmin > tmax) return false;
  }
  return true;
}

template <bool kAnyHit, bool kCount>
Hit traverse(const BvhView& bvh, const Ray& ray, BvhView::Cost* cost) {
  const auto nodes = bvh.nodes();
  const auto triangles = bvh.triangles();
  const BoxRay box_ray = prepare_box_ray(ray);
  const WatertightRay tri_ray = prepare_watertight(ray);
  Hit hit;
  hit.t = ray.tmax;
  std::uint32_t best_ref = kNoHit;
  std::uint32_t stack[format::kBvhMaxDepth];
  std::uint32_t top = 0;
  std::uint32_t current = 0;
  for (;;) {
    const format::BvhNode& n = nodes[current];
    if constexpr (kCount) cost->nodes += 1;
    if (hits_box(n, box_ray, ray.tmin, hit.t)) {
      if (n.count > 0) {
        for (std::uint32_t i = n.offset, end = n.offset + n.count; i < end; ++i) {
          if constexpr (kCount) cost->triangles += 1;
          const format::BvhTriangle& tri = triangles[i];
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
      } else {
        const std::uint32_t first = current + 1, second = n.offset;
        const bool far_first = box_ray.negative[n.axis];
        stack[top++] = far_first ? first : second;
        current = far_first ? second : first;
        continue;
      }
    }
    if (top == 0) break;
    current = stack[--top];
  }
  if (best_ref == kNoHit) return Hit{};
  hit.prim = bvh.prim_ids()[best_ref];
  return hit;
}

}  // namespace

Hit BvhView::intersect(const Ray& ray) const {
  return traverse<false, false>(*this, ray, nullptr);
}

Hit BvhView::intersect_counting(const Ray& ray, Cost& cost) const {
  return traverse<false, true>(*this, ray, &cost);
}

bool BvhView::occluded(const Ray& ray, float* t) const {
  const Hit hit = traverse<true, false>(*this, ray, nullptr);
  if (t != nullptr) *t = hit.t;
  return hit.prim != kNoHit;
}

void trace_rays(const BvhView& bvh, std::span<const Ray> rays, std::span<Hit> hits, bool any_hit,
                unsigned threads) {
  constexpr std::size_t kBatch = 4096;  // rays per task: amortises scheduling, keeps order fixed
  const std::size_t batches = (rays.size() + kBatch - 1) / kBatch;
  parallel_for(batches, threads, [&](std::size_t b) {
    const std::size_t end = std::min(rays.size(), (b + 1) * kBatch);
    for (std::size_t i = b * kBatch; i < end; ++i) {
      hits[i] = any_hit ? traverse<true, false>(bvh, rays[i], nullptr) : bvh.intersect(rays[i]);
    }
  });
}

}  // namespace kiln
