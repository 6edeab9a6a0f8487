#include "kiln/runtime/proximity.hpp"

#include <algorithm>
#include <cmath>

#include "kiln/runtime/triangle_geometry.hpp"
#include "kiln/runtime/watertight.hpp"
#include "ray_box.hpp"

namespace kiln {

namespace {

double box_distance_squared(const format::BvhNode& n, const Vec3d& p) {
  const double q[3] = {p.x, p.y, p.z};
  double sum = 0;
  for (int a = 0; a < 3; ++a) {
    const double d = std::max({double(n.min[a]) - q[a], 0.0, q[a] - double(n.max[a])});
    sum += d * d;
  }
  return sum;
}

bool box_overlaps(const format::BvhNode& n, const Vec3d& lo, const Vec3d& hi) {
  return n.min[0] <= hi.x && n.max[0] >= lo.x && n.min[1] <= hi.y && n.max[1] >= lo.y &&
         n.min[2] <= hi.z && n.max[2] >= lo.z;
}

}  // namespace

ClosestPoint closest_point(const BvhView& bvh, const format::Float3& point, float max_distance) {
  const auto nodes = bvh.nodes();
  const auto triangles = bvh.triangles();
  const Vec3d p = to_d(point);
  double best = double(max_distance) * double(max_distance);
  ClosestPoint result;
  struct Entry {
    std::uint32_t node;
    double d2;
  };
  Entry stack[format::kBvhMaxDepth + 1];
  std::uint32_t top = 0;
  stack[top++] = {0, box_distance_squared(nodes[0], p)};
  while (top > 0) {
    const Entry e = stack[--top];
    if (e.d2 > best) continue;
    const format::BvhNode& n = nodes[e.node];
    if (n.count == 0) {
      Entry first{e.node + 1, box_distance_squared(nodes[e.node + 1], p)};
      Entry second{n.offset, box_distance_squared(nodes[n.offset], p)};
      if (first.d2 > second.d2) std::swap(first, second);
      // Nearer child on top of the stack; each pushed entry is a child of the popped one, so
      // the stack never holds more than one entry per level.
      if (second.d2 <= best) stack[top++] = second;
      if (first.d2 <= best) stack[top++] = first;
      continue;
    }
    for (std::uint32_t i = n.offset, end = n.offset + n.count; i < end; ++i) {
      const auto& t = triangles[i];
      double v = 0, w = 0;
      const Vec3d q = closest_on_triangle(p, to_d(t.v0), to_d(t.v1), to_d(t.v2), v, w);
      const double d2 = dot(q - p, q - p);
      const std::uint32_t prim = bvh.prim_ids()[i];
      // Ties go to the lower primitive id, so SBVH duplicates and traversal order never matter.
      if (d2 < best || (d2 == best && prim < result.prim)) {
        best = d2;
        result.prim = prim;
        result.point = {float(q.x), float(q.y), float(q.z)};
        result.u = float(v);
        result.v = float(w);
      }
    }
  }
  if (result.prim != kNoHit) result.distance = float(std::sqrt(best));
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
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
}

}  // namespace

void triangles_in_box(const BvhView& bvh, const format::Float3& lo_f, const format::Float3& hi_f,
                      std::vector<std::uint32_t>& out) {
  out.clear();
  const Vec3d lo = to_d(lo_f), hi = to_d(hi_f);
  if (!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z)) return;  // empty or NaN box
  collect_prims(
      bvh, [&](const format::BvhNode& n) { return box_overlaps(n, lo, hi); },
      [&](const format::BvhTriangle& t) {
        return triangle_overlaps_box(to_d(t.v0), to_d(t.v1), to_d(t.v2), lo, hi);
      },
      out);
}

bool point_inside(const BvhView& bvh, const format::Float3& p) {
  // Directions with no rational relation to the axes or each other: exact hits on the edges of
  // axis-aligned or grid-like meshes are vanishingly unlikely, and the vote absorbs the rest.
  static constexpr format::Float3 kDirections[5] = {{0.5773503f, 0.5773503f, 0.5773503f},
                                                    {-0.3124515f, 0.8517410f, -0.4206537f},
                                                    {0.7071068f, -0.3826834f, -0.5946036f},
                                                    {-0.6614378f, -0.5f, 0.5590170f},
                                                    {0.1873813f, -0.2763932f, 0.9425779f}};
  std::vector<std::uint32_t> crossed;
  int inside_votes = 0;
  for (const auto& d : kDirections) {
    const Ray ray{p, 0.0f, d, INFINITY};
    const BoxRay box_ray = prepare_box_ray(ray);
    const WatertightRay tri_ray = prepare_watertight(ray);
    float t, u, v;
    collect_prims(
        bvh,
        [&](const format::BvhNode& n) { return enter_box(n, box_ray, 0.0f, INFINITY) != INFINITY; },
        [&](const format::BvhTriangle& tri) {
          return intersect_watertight(tri_ray, tri.v0, tri.v1, tri.v2, 0.0f, INFINITY, t, u, v);
        },
        crossed);
    inside_votes += int(crossed.size() % 2);  // distinct triangles crossed
  }
  return inside_votes >= 3;
}

}  // namespace kiln
