// Point in polygon on a polygon index (docs/FORMAT.md, "Polygon index"), straight on its mapped
// sections and the blob's polygon layer. Every answer follows the half-open boundary rule of
// kiln/runtime/predicates2.hpp: a point is in a polygon when the ray from it towards +x crosses
// the polygon's rings (outer and holes) an odd number of times, edges half-open in y and a
// point on an edge not crossing it; a feature contains the point when one of its polygons does.
#pragma once

#include <cstdint>
#include <memory>
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

/// The quadtree's cells at one level k as a flat 2^k x 2^k table, derived from the validated
/// nodes at open: a query finds its cell by one lookup, then descends only below level k.
/// `xs` / `ys` hold the 2^k + 1 split coordinates of level k exactly as the descent computes
/// them (each a midpoint of its two neighbours of the level above), so the lookup lands in the
/// cell the descent would. A cell whose leaf lies above level k names that leaf and its level.
/// A cell whose leaf answers every point of it alike (no entry, or a first entry wholly inside)
/// holds that answer instead, so most points far from any boundary end at the lookup.
struct PolygonIndexTopGrid {
  /// `code` bit 31 set: the answer for every point of the cell (low 31 bits: the feature, or
  /// kNoFeature); clear: the node index (in `nodes` below).
  static constexpr std::uint32_t kAnswer = 0x80000000u, kNoFeature = 0x7FFFFFFFu;
  std::uint32_t level = 0;               ///< k
  format::Double2 scale;                 ///< 2^k / (bounds' side), the lookup's estimate
  std::vector<double> xs, ys;            ///< split lines, 2^k + 1 each, non-decreasing
  std::vector<std::uint32_t> code;       ///< per cell (row-major, y outer): answer or node
  std::vector<std::uint32_t> node;       ///< per cell: the node (for walks over every entry)
  std::vector<std::uint64_t> empty;      ///< per cell, one bit: no polygon holds a point of it
  std::vector<std::uint8_t> node_level;  ///< per cell: the named node's depth (<= k)
  std::vector<std::uint32_t> feature;    ///< per polygon: its feature (no search per answer)

  /// One 32-byte unit of a leaf record: an entry's head (`head()`: its feature, and its edge
  /// count with format::kPolygonCentreInside, or format::kPolygonWhollyInside), or one of its
  /// edges' endpoints copied from the layer (a.x, a.y, b.x, b.y).
  struct Unit {
    double v[4];
  };
  struct Head {
    std::uint32_t feature, edges;
  };
  /// The nodes again, each leaf's `first` naming its record in `units`: per entry, in order,
  /// its head, then its edges. A point query reads one contiguous record instead of entries,
  /// edge indices and scattered vertices (three dependent loads fewer).
  std::vector<format::PolygonIndexNode> nodes;
  std::vector<Unit> units;
};

/// The top-level table of a validated index (O(4^k + nodes above level k)).
std::shared_ptr<const PolygonIndexTopGrid> make_polygon_index_top_grid(
    const PolygonIndexParts& parts);

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
  /// locate for every point of `points` into `out` (as many): the same answers, in one call
  /// (no call per point: for batches and for embedding loops).
  void locate_many(std::span<const format::Double2> points, std::span<std::uint32_t> out) const;
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
  std::uint32_t locate_inline(const format::Double2& p) const;
  std::uint32_t record_locate(const PolygonIndexTopGrid::Unit* unit, std::uint32_t entries,
                              const format::Box2d& cell, const format::Double2& p) const;
  std::size_t top_cell(const format::Double2& p, std::uint32_t& ix, std::uint32_t& iy) const;
  format::Box2d top_box(std::size_t cell, std::uint32_t ix, std::uint32_t iy) const;

  PolygonIndexParts parts_;
  std::shared_ptr<const PolygonIndexTopGrid> top_;  // shared: views copy cheaply
};

}  // namespace kiln
