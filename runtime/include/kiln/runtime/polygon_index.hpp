// Point in polygon on a polygon index (docs/FORMAT.md, "Polygon index"), straight on its mapped
// sections and the blob's polygon layer. Every answer follows the half-open boundary rule of
// kiln/runtime/predicates2.hpp: a point is in a polygon when the ray from it towards +x crosses
// the polygon's rings (outer and holes) an odd number of times, edges half-open in y and a
// point on an edge not crossing it; a feature contains the point when one of its polygons does.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "kiln/formats/polygon_index.hpp"
#include "kiln/formats/vector.hpp"
#include "kiln/runtime/capabilities.hpp"
#include "kiln/runtime/geo_layer.hpp"
#include "kiln/runtime/ray.hpp"

namespace kiln {

class Blob;

/// The sections of a polygon index, beside the layer it indexes.
struct PolygonIndexParts {
  PolygonLayerView layer;
  format::Box2d bounds;  ///< the root cell
  std::span<const format::PolygonIndexNode> nodes;
  std::span<const format::PolygonIndexEntry> entries;
  std::span<const format::PolygonIndexEdge> edges;
};

/// How many cells a quadtree level holds, and how many edges its cells list.
struct PolygonIndexLevel {
  std::uint64_t leaves = 0, interior = 0, boundary_leaves = 0, edge_refs = 0, entries = 0;
};

/// A validated view of one polygon index. Creating it walks the nodes once (O(nodes + entries)):
/// children after their parent and each node reached once, no deeper than
/// format::kPolygonIndexMaxDepth, leaf entry ranges, polygons and edge ranges in range, every
/// edge's vertices in range; so no query can read out of range, loop or recurse too deep,
/// whatever the bytes (a forged edge may give a wrong answer, never a crash). The layer's offsets
/// were checked by Blob::open. Throws BlobError naming `name` otherwise.
class PolygonIndexView {
 public:
  explicit PolygonIndexView(const PolygonIndexParts& parts,
                            const std::string& name = "polygon-index");
  /// The structure named `name` of a blob, over the blob's polygon layer.
  static PolygonIndexView from_blob(const Blob& blob, const std::string& name = "polygon-index");

  /// The lowest feature index containing `p`, or PolygonQueries::kNone.
  std::uint32_t locate(const format::Double2& p) const;
  /// The same, counting nodes visited and edges tested into `cost`.
  std::uint32_t locate_counting(const format::Double2& p, Cost& cost) const;
  /// Every feature containing `p`, ascending, into `out` (cleared first).
  void locate_all(const format::Double2& p, std::vector<std::uint32_t>& out) const;
  /// Every feature whose closed area meets the closed box, ascending, into `out`.
  void features_in_box(const format::Box2d& box, std::vector<std::uint32_t>& out) const;
  /// The leaves in storage order.
  void cells(std::vector<IndexCell2>& out) const;
  /// Per level (index = depth): leaves, interior nodes, edge lists.
  std::vector<PolygonIndexLevel> levels() const;

  /// The feature owning polygon `polygon`.
  std::uint32_t feature_of(std::uint32_t polygon) const;
  const PolygonIndexParts& parts() const { return parts_; }

 private:
  template <class Visit>
  void visit_leaf(const format::Double2& p, Visit&& visit, Cost* cost) const;
  bool entry_contains(const format::PolygonIndexEntry& e, const format::Box2d& cell,
                      const format::Double2& p, Cost* cost) const;
  void validate(const std::string& name) const;

  PolygonIndexParts parts_;
};

}  // namespace kiln
