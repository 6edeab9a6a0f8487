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

/// What the view derives at open from the validated sections for `locate` and `locate_many`
/// (docs/FORMAT.md, "Polygon index", "Top-level table" and "Leaf records"): the quadtree's cells
/// at one level k as a flat 2^k x 2^k table of codes, so that a query finds its cell by one
/// lookup, then reads at most a branch entry (or, deeper, a few) and one leaf record.
struct PolygonIndexTopGrid {
  /// Code bit 31 set: the answer for every point of the cell (low 31 bits: the feature, or
  /// kNoFeature). Else bit 30 clear: the leaf record at word `code` of `records`; set: a branch,
  /// 4^d codes at `code[code & kOffset]`, d = 1 + (code >> 28 & 3) <= kFine, indexed by the
  /// child bits of d descent levels interleaved (first level most significant).
  static constexpr std::uint32_t kAnswer = 0x80000000u, kNoFeature = 0x7FFFFFFFu;
  static constexpr std::uint32_t kBranch = 0x40000000u, kOffset = 0x0FFFFFFFu;
  static constexpr std::uint32_t kRecordOffset = 0x3FFFFFFFu;
  /// A record group holds at most this many polygons (one bit each in its masks).
  static constexpr std::uint32_t kGroupPolygons = 31;
  /// Branches below the table span at most this many levels; the split lines go as deep, so
  /// that one column lookup per axis gives both the table cell and the branch entry.
  static constexpr std::uint32_t kFine = 3;
  /// How far (in fine columns) a split line's uniform estimate may lie from its index for the
  /// clear bits to be set.
  static constexpr double kEstimateSlack = 2;
  std::uint32_t level = 0;  ///< k
  std::uint32_t last = 0;   ///< 2^(k + kFine) - 1: the last fine column and row
  format::Double2 scale;    ///< 2^(k + kFine) / (bounds' side), the uniform estimate's
  /// The split lines of level k + kFine (2^(k + kFine) + 1 per axis) exactly as the descent
  /// computes them (each a midpoint of its two neighbours of the level above), non-decreasing:
  /// the column of p is the last line <= p.x, the one the descent reaches.
  std::vector<double> xs, ys;
  /// Codes: per table cell (row-major, y outer), then the branches' entries.
  std::vector<std::uint32_t> code;
  /// Per table cell, one bit: the cell and its eight neighbours code "none". Set only where
  /// every split line lies within kEstimateSlack of its uniform estimate (checked here), so that
  /// a point whose estimated cell is clear is in no polygon.
  std::vector<std::uint64_t> clear;
  std::vector<std::uint32_t> feature;  ///< per polygon: its feature (no search per answer)
  /// Leaf records in 8-byte words (layout: docs/FORMAT.md; answered by
  /// runtime/src/polygon_index_records.cpp).
  std::vector<std::uint64_t> records;
};

/// A leaf record's answer for a point: the lowest feature holding it, or PolygonQueries::kNone.
using PolygonRecordKernel = std::uint32_t (*)(const std::uint64_t* record,
                                              const format::Double2& p);

/// The table, branches and leaf records of a validated index (O(4^k + nodes + entries + edge
/// references x log)); null when entries share edges or the records would outgrow their offsets.
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

  PolygonIndexParts parts_;
  std::shared_ptr<const PolygonIndexTopGrid> top_;  // shared: views copy cheaply
  // A leaf record's answer (runtime/src/polygon_index_records.cpp), the kernel for this CPU.
  PolygonRecordKernel record_ = nullptr;
};

}  // namespace kiln
