// Proximity, containment and range queries on a BVH or a SAH k-d tree: closest point on the
// surface, point inside a closed mesh, triangles overlapping a box. Both structures give the same
// answers under the same tie rules.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include "kiln/formats/geometry.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/kdtree.hpp"

namespace kiln {

struct ClosestPoint {
  float distance = std::numeric_limits<float>::infinity();
  std::uint32_t prim = kNoHit;  // kNoHit when nothing lies within max_distance
  format::Float3 point{0, 0, 0};
  float u = 0, v = 0;  // barycentric weights of the triangle's second and third corners
};

// Branch and bound: nodes are visited nearest box first and pruned by box distance.
ClosestPoint closest_point(const BvhView& bvh, const format::Float3& p,
                           float max_distance = std::numeric_limits<float>::infinity());

// Every triangle that intersects the box (exact separating-axis test, Akenine-Moller 2001),
// as sorted, unique original primitive ids, appended to `out` after clearing it.
void triangles_in_box(const BvhView& bvh, const format::Float3& lo, const format::Float3& hi,
                      std::vector<std::uint32_t>& out);

// Inside/outside by ray parity: five rays in fixed, irrational directions, each counting the
// distinct triangles it crosses; the majority wins. Meaningful for closed meshes; on an open
// mesh it still answers (the manifest says whether the mesh is closed).
bool point_inside(const BvhView& bvh, const format::Float3& p);

// The same three queries on a k-d tree: cells are walked from the tree's root bounds (nearest
// cell first for the closest point, pruned by cell distance), and the whole triangles a leaf
// references are tested. A point outside the root bounds is fine.
ClosestPoint closest_point(const KdTreeView& tree, const format::Float3& p,
                           float max_distance = std::numeric_limits<float>::infinity());
void triangles_in_box(const KdTreeView& tree, const format::Float3& lo, const format::Float3& hi,
                      std::vector<std::uint32_t>& out);
bool point_inside(const KdTreeView& tree, const format::Float3& p);

}  // namespace kiln
