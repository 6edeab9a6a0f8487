// What the proximity queries answer: a closest point on a surface, and a neighbouring point.
#pragma once

#include <cstdint>
#include <limits>

#include "kiln/formats/geometry.hpp"
#include "kiln/runtime/ray.hpp"

namespace kiln {

/// The closest point on a triangle surface; prim == kNoHit when nothing lies within the
/// query's max_distance.
struct ClosestPoint {
  float distance = std::numeric_limits<float>::infinity();
  std::uint32_t prim = kNoHit;
  format::Float3 point{0, 0, 0};
  float u = 0, v = 0;  // barycentric weights of the triangle's second and third corners
};

/// One neighbour: a point's id (its vertex index) and its squared distance to the query,
/// computed in float as (dx*dx + dy*dy) + dz*dz. The knn output record of `kiln query`.
struct Neighbor {
  std::uint32_t id;
  float distance2;
};
static_assert(sizeof(Neighbor) == 8);

/// Answers are ordered by distance, then id: ties go to the lower id, so results equal a
/// brute-force scan's exactly.
inline bool closer(const Neighbor& a, const Neighbor& b) {
  return a.distance2 < b.distance2 || (a.distance2 == b.distance2 && a.id < b.id);
}

}  // namespace kiln
