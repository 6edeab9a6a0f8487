// An octree over triangles straight on its mapped sections: front-to-back ray traversal, and the
// proximity, containment and range queries.
#pragma once

#include <bit>
#include <cstdint>
#include <functional>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "kiln/formats/geometry.hpp"
#include "kiln/formats/octree.hpp"
#include "kiln/runtime/query_results.hpp"
#include "kiln/runtime/ray.hpp"

namespace kiln {

class Blob;

/// A validated view of one octree; a RayStructure (kiln/runtime/ray_structure.hpp). Creating it
/// walks the nodes once and reads every reference (O(nodes + references)): nodes in
/// breadth-first order (each node's children contiguous, after it, and every node but the root
/// the child of exactly one node), no node deeper than kOctreeMaxDepth, leaf ranges consecutive
/// and in range, primitive ids naming stored triangles, a finite root cell; so no query can read
/// out of range, loop or overflow its fixed stack, whatever the bytes. Throws BlobError
/// otherwise.
class OctreeView {
 public:
  using HitType = Hit;

  OctreeView(std::span<const format::OctreeNode> nodes, std::span<const std::uint32_t> prim_ids,
             std::span<const format::RayTriangle> triangles, const format::Box3f& bounds,
             const std::string& name = "octree");
  /// The structure named `name` of a blob; throws BlobError when the blob has no structure of
  /// that name or it is not an octree.
  static OctreeView from_blob(const Blob& blob, const std::string& name);

  /// Closest hit in (tmin, tmax); Hit::prim == kNoHit on a miss.
  Hit intersect(const Ray& ray) const;
  /// The first hit found in (tmin, tmax), not necessarily the closest.
  Hit intersect_any(const Ray& ray) const;
  /// Whether anything lies in (tmin, tmax).
  bool occluded(const Ray& ray) const;
  /// The closest hit, adding its node visits and triangle tests to `cost`.
  Hit intersect_counting(const Ray& ray, Cost& cost) const;

  std::span<const format::OctreeNode> nodes() const { return nodes_; }
  std::span<const std::uint32_t> prim_ids() const { return prim_ids_; }
  std::span<const format::RayTriangle> triangles() const { return triangles_; }
  /// The root cell.
  const format::Box3f& bounds() const { return bounds_; }
  /// The deepest node (root = 0), as the validating walk found it.
  std::uint32_t depth() const { return depth_; }

 private:
  std::span<const format::OctreeNode> nodes_;
  std::span<const std::uint32_t> prim_ids_;
  std::span<const format::RayTriangle> triangles_;
  format::Box3f bounds_;
  std::uint32_t depth_ = 0;
};

/// Calls visit(leaf node index, entry, exit) for every leaf whose cell the ray meets in
/// [tmin, tmax], in the order the ray traversal reaches them (front to back by entry distance),
/// with the cell's unpadded entry and exit distances; no pruning by hits. For tests and tools.
void octree_leaves_along(const OctreeView& tree, const Ray& ray,
                         const std::function<void(std::uint32_t, float, float)>& visit);

/// Calls leaf(node, cell) for every leaf, depth first in octant order, with the cell that the
/// builder and the traversal give it (format::octree_child_cell from the root cell down).
template <class Leaf>
void for_each_octree_leaf(const OctreeView& tree, Leaf leaf) {
  struct Entry {
    std::uint32_t node;
    format::Box3f cell;
  };
  std::vector<Entry> stack{{0, tree.bounds()}};
  while (!stack.empty()) {
    const Entry e = stack.back();
    stack.pop_back();
    const format::OctreeNode& n = tree.nodes()[e.node];
    if (n.is_leaf()) {
      leaf(n, e.cell);
      continue;
    }
    std::uint32_t child = n.first_child() + std::uint32_t(std::popcount(n.child_mask()));
    for (std::uint32_t octant = 8; octant-- > 0;)
      if (n.child_mask() >> octant & 1u)
        stack.push_back({--child, format::octree_child_cell(e.cell, octant)});
  }
}

/// The proximity queries, with the same answers and tie rules as on any triangle structure:
/// cells are walked from the root cell (nearest cell first for the closest point, pruned by cell
/// distance), and the whole triangles a leaf references are tested. A point outside the root
/// cell is fine.
/// The closest point of the surface within `max_distance`; ties go to the lower primitive id.
ClosestPoint closest_point(const OctreeView& tree, const format::Float3& p,
                           float max_distance = std::numeric_limits<float>::infinity());
/// Every triangle that intersects the box, as sorted, unique primitive ids, into `out`.
void triangles_in_box(const OctreeView& tree, const format::Float3& lo, const format::Float3& hi,
                      std::vector<std::uint32_t>& out);
/// Inside/outside by a majority of five ray-parity votes (meaningful for closed meshes).
bool point_inside(const OctreeView& tree, const format::Float3& p);

}  // namespace kiln
