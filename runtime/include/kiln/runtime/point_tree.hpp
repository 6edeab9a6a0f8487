// k-nearest-neighbour and radius searches on a point k-d tree over 3D points (a point set, or a
// triangle scene's vertices), straight on its mapped sections.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "kiln/formats/geometry.hpp"
#include "kiln/formats/point_tree.hpp"
#include "kiln/runtime/query_results.hpp"

namespace kiln {

class Blob;

/// A validated view of one point k-d tree. Creating it walks the nodes once (O(nodes)): nodes in
/// depth-first order, no deeper than format::kPointMaxDepth, leaf ranges consecutive and covering
/// every point exactly once; so a search cannot read out of range, loop or recurse too deep,
/// whatever the bytes. Throws BlobError otherwise.
class PointTreeView {
 public:
  PointTreeView(std::span<const format::PointNode> nodes, std::span<const format::Float3> points,
                std::span<const std::uint32_t> ids, const format::Box3f& bounds,
                const std::string& name = "points");
  /// The structure named `name` of a blob; throws BlobError when the blob has no structure of
  /// that name or it is not a point k-d tree.
  static PointTreeView from_blob(const Blob& blob, const std::string& name = "points");

  /// The min(k, point count) nearest points, k = out.size(), written to `out` sorted by
  /// (distance, id); returns how many were written. No allocation.
  std::size_t nearest(const format::Float3& query, std::span<Neighbor> out) const;
  /// Every point with squared distance <= radius * radius (in float), sorted by (distance, id),
  /// into `out` (cleared first).
  void within_radius(const format::Float3& query, float radius, std::vector<Neighbor>& out) const;

  std::span<const format::PointNode> nodes() const { return nodes_; }
  std::span<const format::Float3> points() const { return points_; }
  std::span<const std::uint32_t> ids() const { return ids_; }
  /// The box around every point.
  const format::Box3f& bounds() const { return bounds_; }

 private:
  std::span<const format::PointNode> nodes_;
  std::span<const format::Float3> points_;
  std::span<const std::uint32_t> ids_;
  format::Box3f bounds_;
};

}  // namespace kiln
