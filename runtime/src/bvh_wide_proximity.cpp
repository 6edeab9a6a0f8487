// Closest point, point inside and box queries on a wide BVH (kiln/runtime/bvh_wide.hpp), scalar:
// they are not on the ray path, and read the same bytes as the traversal kernels.
#include "kiln/runtime/bvh_wide.hpp"
#include "kiln/runtime/triangle_geometry.hpp"
#include "kiln/runtime/watertight.hpp"
#include "proximity_detail.hpp"
#include "ray_box.hpp"

namespace kiln {

using namespace proximity_detail;

namespace {

struct ChildBox {
  float lo[3], hi[3];
};

template <class Node>
ChildBox child_box(const Node& n, int k) {
  ChildBox b;
  format::bvh_child_box(n, k, b.lo, b.hi);
  return b;
}

format::RayTriangle lane_triangle(const format::BvhTrianglePacket& p, std::uint32_t lane) {
  return {{p.v[0][0][lane], p.v[0][1][lane], p.v[0][2][lane]},
          {p.v[1][0][lane], p.v[1][1][lane], p.v[1][2][lane]},
          {p.v[2][0][lane], p.v[2][1][lane], p.v[2][2][lane]}};
}

// Calls visit(triangle, prim) for every lane of a leaf's packets.
template <class Visit>
void for_each_lane(const BvhWideView& bvh, std::uint32_t word, std::uint32_t packets,
                   Visit&& visit) {
  for (const format::BvhTrianglePacket& p : bvh.leaf(word, packets))
    for (std::uint32_t lane = 0; lane < format::kBvhPacketSize; ++lane)
      visit(lane_triangle(p, lane), p.prim[lane]);
}

template <int W, class Node>
ClosestPoint closest_wide(const BvhWideView& bvh, const format::Float3& point, float max_distance) {
  const format::Double3 p = to_d(point);
  double best = double(max_distance) * double(max_distance);
  ClosestPoint result;
  struct Entry {
    std::uint32_t word, packets;
    double d2;
  };
  // Each pop pushes at most W children: (W - 1) per level beyond the first.
  Entry stack[(W - 1) * format::kBvhMaxDepth + 2];
  std::uint32_t top = 0;
  stack[top++] = {0, 0, 0.0};
  while (top > 0) {
    const Entry e = stack[--top];
    if (e.d2 > best) continue;
    if (e.word & format::kBvhLeafFlag) {
      for_each_lane(bvh, e.word, e.packets, [&](const format::RayTriangle& t, std::uint32_t id) {
        consider_closest(p, t, id, best, result);
      });
      continue;
    }
    const auto& n = bvh.node<Node>(e.word);
    Entry kids[W];
    int count = 0;
    for (int k = 0; k < W; ++k) {
      if (n.child[k] == format::kBvhLeafFlag && n.packets[k] == 0) continue;  // empty
      const ChildBox b = child_box(n, k);
      const double d2 = box_distance_squared(b.lo, b.hi, p);
      if (d2 > best) continue;
      int j = count++;
      for (; j > 0 && kids[j - 1].d2 < d2; --j) kids[j] = kids[j - 1];  // farthest first
      kids[j] = {n.child[k], n.packets[k], d2};
    }
    for (int k = 0; k < count; ++k) stack[top++] = kids[k];  // nearest on top
  }
  finish_closest(best, result);
  return result;
}

// Sorted, distinct primitive ids of the lanes in every leaf whose box passes `enter` (from the
// root down) and that pass `keep`.
template <int W, class Node, class Enter, class Keep>
void collect_wide(const BvhWideView& bvh, Enter enter, Keep keep, std::vector<std::uint32_t>& out) {
  out.clear();
  struct Entry {
    std::uint32_t word, packets;
  };
  Entry stack[(W - 1) * format::kBvhMaxDepth + 2];
  std::uint32_t top = 0;
  stack[top++] = {0, 0};
  while (top > 0) {
    const Entry e = stack[--top];
    if (e.word & format::kBvhLeafFlag) {
      for_each_lane(bvh, e.word, e.packets, [&](const format::RayTriangle& t, std::uint32_t id) {
        if (keep(t)) out.push_back(id);
      });
      continue;
    }
    const auto& n = bvh.node<Node>(e.word);
    for (int k = 0; k < W; ++k) {
      if (n.child[k] == format::kBvhLeafFlag && n.packets[k] == 0) continue;
      const ChildBox b = child_box(n, k);
      if (enter(b.lo, b.hi)) stack[top++] = {n.child[k], n.packets[k]};
    }
  }
  sort_unique(out);
}

template <class Enter, class Keep>
void collect(const BvhWideView& bvh, Enter enter, Keep keep, std::vector<std::uint32_t>& out) {
  if (bvh.width() == 16)
    collect_wide<16, format::BvhNode16>(bvh, enter, keep, out);
  else if (bvh.quantized())
    bvh.width() == 4 ? collect_wide<4, format::BvhQNode4>(bvh, enter, keep, out)
                     : collect_wide<8, format::BvhQNode8>(bvh, enter, keep, out);
  else
    bvh.width() == 4 ? collect_wide<4, format::BvhNode4>(bvh, enter, keep, out)
                     : collect_wide<8, format::BvhNode8>(bvh, enter, keep, out);
}

}  // namespace

ClosestPoint closest_point(const BvhWideView& bvh, const format::Float3& p, float max_distance) {
  if (bvh.width() == 16) return closest_wide<16, format::BvhNode16>(bvh, p, max_distance);
  if (bvh.quantized())
    return bvh.width() == 4 ? closest_wide<4, format::BvhQNode4>(bvh, p, max_distance)
                            : closest_wide<8, format::BvhQNode8>(bvh, p, max_distance);
  return bvh.width() == 4 ? closest_wide<4, format::BvhNode4>(bvh, p, max_distance)
                          : closest_wide<8, format::BvhNode8>(bvh, p, max_distance);
}

void triangles_in_box(const BvhWideView& bvh, const format::Float3& lo_f,
                      const format::Float3& hi_f, std::vector<std::uint32_t>& out) {
  out.clear();
  format::Box3d box;
  if (!prepare_query_box(lo_f, hi_f, box)) return;  // empty or NaN box
  collect(
      bvh, [&](const float* lo, const float* hi) { return box_overlaps(lo, hi, box); },
      [&](const format::RayTriangle& t) { return triangle_in_box(t, box); }, out);
}

bool point_inside(const BvhWideView& bvh, const format::Float3& p) {
  return inside_by_vote(p, [&](const Ray& ray, std::vector<std::uint32_t>& crossed) {
    const BoxRay box_ray = prepare_box_ray(ray);
    const WatertightRay tri_ray = prepare_watertight(ray);
    collect(
        bvh,
        [&](const float* lo, const float* hi) {
          float tmin = 0.0f, tmax = INFINITY;
          return clip_to_box(lo, hi, box_ray, tmin, tmax);
        },
        [&](const format::RayTriangle& t) { return ray_crosses(tri_ray, t); }, crossed);
  });
}

}  // namespace kiln
