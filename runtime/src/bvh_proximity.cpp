// Closest point, point inside and box queries on a BVH (kiln/runtime/bvh.hpp).
#include "kiln/runtime/bvh.hpp"

#include "kiln/runtime/triangle_geometry.hpp"
#include "kiln/runtime/watertight.hpp"
#include "proximity_detail.hpp"
#include "ray_box.hpp"

namespace kiln {

using namespace proximity_detail;

ClosestPoint closest_point(const BvhView& bvh, const format::Float3& point, float max_distance) {
  const auto nodes = bvh.nodes();
  const auto triangles = bvh.triangles();
  const format::Double3 p = to_d(point);
  double best = double(max_distance) * double(max_distance);
  ClosestPoint result;
  struct Entry {
    std::uint32_t node;
    double d2;
  };
  auto entry = [&](std::uint32_t i) {
    return Entry{i, box_distance_squared(nodes[i].min, nodes[i].max, p)};
  };
  Entry stack[format::kBvhMaxDepth + 1];
  std::uint32_t top = 0;
  stack[top++] = entry(0);
  while (top > 0) {
    const Entry e = stack[--top];
    if (e.d2 > best) continue;
    const format::BvhNode& n = nodes[e.node];
    if (n.count == 0) {
      Entry first = entry(e.node + 1), second = entry(n.offset);
      if (first.d2 > second.d2) std::swap(first, second);
      // Nearer child on top of the stack; each pushed entry is a child of the popped one, so
      // the stack never holds more than one entry per level.
      if (second.d2 <= best) stack[top++] = second;
      if (first.d2 <= best) stack[top++] = first;
      continue;
    }
    for (std::uint32_t i = n.offset, end = n.offset + n.count; i < end; ++i)
      consider_closest(p, triangles[i], bvh.prim_ids()[i], best, result);
  }
  finish_closest(best, result);
  return result;
}

namespace {

// Sorted, distinct primitive ids of the references in every leaf whose box passes `enter` and
// that pass `keep`; SBVH references repeat, hence the dedup.
template <class Enter, class Keep>
void collect_prims(const BvhView& bvh, Enter enter, Keep keep, std::vector<std::uint32_t>& out) {
  out.clear();
  const auto nodes = bvh.nodes();
  std::uint32_t stack[format::kBvhMaxDepth + 1];
  std::uint32_t top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const std::uint32_t index = stack[--top];
    const format::BvhNode& n = nodes[index];
    if (!enter(n)) continue;
    if (n.count == 0) {
      stack[top++] = n.offset;
      stack[top++] = index + 1;
      continue;
    }
    for (std::uint32_t i = n.offset, end = n.offset + n.count; i < end; ++i)
      if (keep(bvh.triangles()[i])) out.push_back(bvh.prim_ids()[i]);
  }
  sort_unique(out);
}

}  // namespace

void triangles_in_box(const BvhView& bvh, const format::Float3& lo_f, const format::Float3& hi_f,
                      std::vector<std::uint32_t>& out) {
  out.clear();
  format::Box3d box;
  if (!prepare_query_box(lo_f, hi_f, box)) return;  // empty or NaN box
  collect_prims(
      bvh, [&](const format::BvhNode& n) { return box_overlaps(n.min, n.max, box); },
      [&](const format::RayTriangle& t) { return triangle_in_box(t, box); }, out);
}

bool point_inside(const BvhView& bvh, const format::Float3& p) {
  return inside_by_vote(p, [&](const Ray& ray, std::vector<std::uint32_t>& crossed) {
    const BoxRay box_ray = prepare_box_ray(ray);
    const WatertightRay tri_ray = prepare_watertight(ray);
    collect_prims(
        bvh,
        [&](const format::BvhNode& n) { return enter_box(n, box_ray, 0.0f, INFINITY) != INFINITY; },
        [&](const format::RayTriangle& t) { return ray_crosses(tri_ray, t); }, crossed);
  });
}

}  // namespace kiln
