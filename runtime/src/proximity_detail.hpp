// Pieces shared by the proximity queries of the triangle structures (each structure's
// *_proximity.cpp): box distances, the per-triangle predicates with their tie rules, and the
// ray-parity vote.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "kiln/formats/ray_triangle.hpp"
#include "kiln/runtime/query_results.hpp"
#include "kiln/runtime/ray.hpp"
#include "kiln/runtime/triangle_geometry.hpp"
#include "kiln/runtime/watertight.hpp"

namespace kiln::proximity_detail {

// Squared distance from p to the closed box [lo, hi]; 0 inside.
inline double box_distance_squared(const float lo[3], const float hi[3], const format::Double3& p) {
  const double q[3] = {p.x, p.y, p.z};
  double sum = 0;
  for (int a = 0; a < 3; ++a) {
    const double d = std::max({double(lo[a]) - q[a], 0.0, q[a] - double(hi[a])});
    sum += d * d;
  }
  return sum;
}

// Whether the closed boxes [lo, hi] and q share a point.
inline bool box_overlaps(const float lo[3], const float hi[3], const format::Box3d& q) {
  return lo[0] <= q.max.x && hi[0] >= q.min.x && lo[1] <= q.max.y && hi[1] >= q.min.y &&
         lo[2] <= q.max.z && hi[2] >= q.min.z;
}

// Offers triangle `prim` to a closest-point search whose best squared distance so far is
// `best`. Ties go to the lower primitive id, so duplicated references and traversal order never
// change the answer.
inline void consider_closest(const format::Double3& p, const format::RayTriangle& t,
                             std::uint32_t prim, double& best, ClosestPoint& result) {
  double v = 0, w = 0;
  const format::Double3 q = closest_on_triangle(p, to_d(t.v0), to_d(t.v1), to_d(t.v2), v, w);
  const double d2 = dot(q - p, q - p);
  if (d2 < best || (d2 == best && prim < result.prim)) {
    best = d2;
    result.prim = prim;
    result.point = {float(q.x), float(q.y), float(q.z)};
    result.u = float(v);
    result.v = float(w);
  }
}

inline void finish_closest(double best, ClosestPoint& result) {
  if (result.prim != kNoHit) result.distance = float(std::sqrt(best));
}

// The query box in double; false when it is empty or has a NaN corner.
inline bool prepare_query_box(const format::Float3& lo, const format::Float3& hi,
                              format::Box3d& box) {
  box = {to_d(lo), to_d(hi)};
  return box.min.x <= box.max.x && box.min.y <= box.max.y && box.min.z <= box.max.z;
}

inline bool triangle_in_box(const format::RayTriangle& t, const format::Box3d& box) {
  return triangle_overlaps_box(to_d(t.v0), to_d(t.v1), to_d(t.v2), box.min, box.max);
}

// Whether the ray crosses the triangle anywhere in (0, inf).
inline bool ray_crosses(const WatertightRay& ray, const format::RayTriangle& t) {
  float hit_t, u, v;
  return intersect_watertight(ray, t.v0, t.v1, t.v2, 0.0f, INFINITY, hit_t, u, v);
}

// Primitive ids gathered from leaves (where a triangle may be referenced several times) as a
// sorted set.
inline void sort_unique(std::vector<std::uint32_t>& ids) {
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
}

// Inside/outside by a majority of five ray-parity votes. `crossed(ray, ids)` fills `ids` with
// the distinct triangles the ray crosses in (0, inf).
template <class Crossed>
bool inside_by_vote(const format::Float3& p, Crossed&& crossed) {
  // Directions with no rational relation to the axes or each other: exact hits on the edges of
  // axis-aligned or grid-like meshes are vanishingly unlikely, and the vote absorbs the rest.
  static constexpr format::Float3 kDirections[5] = {{0.5773503f, 0.5773503f, 0.5773503f},
                                                    {-0.3124515f, 0.8517410f, -0.4206537f},
                                                    {0.7071068f, -0.3826834f, -0.5946036f},
                                                    {-0.6614378f, -0.5f, 0.5590170f},
                                                    {0.1873813f, -0.2763932f, 0.9425779f}};
  std::vector<std::uint32_t> ids;
  int inside_votes = 0;
  for (const auto& d : kDirections) {
    crossed(Ray{p, 0.0f, d, INFINITY}, ids);
    inside_votes += int(ids.size() % 2);
  }
  return inside_votes >= 3;
}

}  // namespace kiln::proximity_detail
