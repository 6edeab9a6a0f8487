// Range, k-nearest and radius queries on a bucket PR quadtree over a 2D point table, straight on
// its mapped sections (formats/quadtree.hpp).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "kiln/formats/quadtree.hpp"
#include "kiln/runtime/capabilities.hpp"
#include "kiln/runtime/ray.hpp"

namespace kiln {

class Blob;

/// A validated view of one quadtree. Creating it walks the nodes once (O(nodes)): depth-first
/// order with every child inside its parent's node and point ranges, siblings in ascending
/// quadrant order, leaves no deeper than format::kQuadMaxDepth, the leaves' points consecutive
/// and covering every point exactly once, every id below `table_points`; so no query can read
/// out of range, loop or overflow its stack, whatever the bytes. Throws BlobError otherwise.
/// Results follow capabilities.hpp's Point2Queries: indices into the table's points, sorted as
/// a brute-force scan sorts them (ascending index; (distance, index) for neighbours, distances
/// by format::distance_squared).
class QuadtreeView {
 public:
  QuadtreeView(std::span<const format::QuadNode> nodes, std::span<const format::Double2> points,
               std::span<const std::uint32_t> ids, const format::Box2d& root,
               std::uint64_t table_points, const std::string& name = "quadtree");
  /// The structure named `name` of a blob; throws BlobError when the blob has no structure of
  /// that name or it is not a quadtree.
  static QuadtreeView from_blob(const Blob& blob, const std::string& name = "quadtree");

  /// Every point in the closed box, ascending index, into `out` (cleared first). A subtree
  /// whose cell lies inside the box is reported without testing its points.
  void range(const format::Box2d& box, std::vector<std::uint32_t>& out) const;
  /// The same, counting nodes visited and points tested into `cost`.
  void range_counting(const format::Box2d& box, std::vector<std::uint32_t>& out, Cost& cost) const;
  /// The min(k, point count) nearest, k = out.size(), by (distance, index): best first over
  /// cells by their distance, the k best so far in a bounded heap. Returns how many.
  std::size_t nearest(const format::Double2& q, std::span<Neighbor2> out) const;
  /// Every point with squared distance <= radius^2, by (distance, index), into `out`.
  void within_radius(const format::Double2& q, double radius, std::vector<Neighbor2>& out) const;
  /// The leaves' cells in storage order, with their level and bucket size.
  void cells(std::vector<IndexCell2>& out) const;

  std::span<const format::QuadNode> nodes() const { return nodes_; }
  std::span<const format::Double2> points() const { return points_; }
  std::span<const std::uint32_t> ids() const { return ids_; }
  const format::Box2d& root() const { return root_; }

 private:
  template <bool kCount>
  void range_impl(const format::Box2d& box, std::vector<std::uint32_t>& out, Cost* cost) const;

  std::span<const format::QuadNode> nodes_;
  std::span<const format::Double2> points_;
  std::span<const std::uint32_t> ids_;
  format::Box2d root_;
  std::uint64_t table_points_ = 0;
};

}  // namespace kiln
