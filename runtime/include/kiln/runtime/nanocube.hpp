// The nanocube's view (Lins, Klosowski & Scheidegger 2013) and, as its reference, a brute-force
// scan of the mapped event table; both answer EventQueries with the same snapping
// (docs/FORMAT.md, "Nanocube").
#pragma once

#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "kiln/formats/nanocube.hpp"
#include "kiln/runtime/capabilities.hpp"
#include "kiln/runtime/event_table.hpp"

namespace kiln {

class Blob;
struct StructureInfo;

/// How a cube cuts space and time: cells at `max_level`, bins of `time_bin` seconds from
/// `time_origin`, `bin_count` of them.
struct EventGrid {
  std::uint32_t max_level = 20;
  std::int64_t time_bin = 3600, time_origin = 0;
  std::uint32_t bin_count = 0;
};

/// A selection resolved against a table and a grid.
struct ResolvedSelection {
  std::uint32_t x0 = 0, x1 = 0, y0 = 0, y1 = 0;  ///< inclusive cells at max_level
  bool empty = false;                            ///< no cell (box outside the tile)
  std::int64_t b0 = 0, b1 = 0;                   ///< bins [b0, b1), may lie outside the cube
  std::vector<std::vector<char>> allowed;        ///< per category: empty = all, else per code
  EventSnap snap;
};

/// Snaps and resolves `selection` (throws std::invalid_argument for an unknown category or a
/// tile outside the grid).
ResolvedSelection resolve_event_selection(const EventSelection& selection,
                                          const EventTableView& table, const EventGrid& grid);

/// "1h", "15m", "1d", "1w", "30s", or a plain number of seconds; throws std::invalid_argument.
std::int64_t parse_duration(std::string_view text);

/// The nanocube over a blob's mapped bytes, validated at open: every edge, content and series
/// index in range, children before parents, series bins increasing, so no query can read out
/// of range or loop, whatever the bytes.
class NanocubeView final : public EventQueries {
 public:
  static NanocubeView from_blob(const Blob& blob, const StructureInfo& info);

  const EventGrid& grid() const { return grid_; }
  const EventTableView& table() const { return table_; }
  std::span<const format::NanocubeNode> nodes() const { return nodes_; }
  std::span<const std::uint64_t> dimension_nodes() const { return dimension_nodes_; }

  std::uint32_t finest_level() const override { return grid_.max_level; }
  std::int64_t time_bin() const override { return grid_.time_bin; }
  EventSnap snap(const EventSelection& selection) const override;
  std::uint64_t count(const EventSelection& selection) const override;
  std::vector<std::pair<std::int64_t, std::uint64_t>> series(
      const EventSelection& selection, std::int64_t bin_seconds) const override;
  std::vector<EventTileCount> tiles(const EventSelection& selection,
                                    std::uint32_t zoom) const override;
  std::vector<EventLabelCount> topk(const EventSelection& selection, std::string_view by,
                                    std::size_t k) const override;
  /// topk, and how many (node, label) counts it read from the series (0 when the rankings alone
  /// answer it; with the threshold algorithm, labels ruled out by the rankings are never read).
  std::vector<EventLabelCount> topk_counting(const EventSelection& selection, std::string_view by,
                                             std::size_t k, std::size_t& labels_counted) const;
  /// What one top-k did: the way taken and its work (tests and the benchmark read it).
  struct TopkTrace {
    enum class Path { kNone, kRankings, kCounted, kThreshold };
    Path path = Path::kNone;         ///< kRankings: all-time rankings alone; kThreshold: the walk
    std::size_t labels_counted = 0;  ///< labels counted exactly over the walked nodes
    std::size_t block_lists = 0;     ///< rankings of time blocks the walk read (not all-time)
    std::size_t walked_nodes = 0;    ///< covered nodes the walk ranked (the rest were counted)
    std::size_t counted_nodes = 0;   ///< covered nodes whose labels were each counted
    std::size_t counted_labels = 0;  ///< labels those nodes hold (over all time)
  };
  std::vector<EventLabelCount> topk_traced(const EventSelection& selection, std::string_view by,
                                           std::size_t k, TopkTrace& trace) const;
  /// Topkube's ranking of category `c` under spatial node `node` (counts over all time).
  std::span<const format::NanocubeRankEntry> ranking(std::size_t c, std::uint32_t node) const;
  /// Block levels (0: none) and level i's bins per block (docs/FORMAT.md §24.2).
  std::uint32_t block_levels() const { return block_levels_; }
  std::uint64_t block_size(std::uint32_t level) const {
    return format::nanocube_block_size(block_shift_, block_stride_, level);
  }
  /// The finest block level stored for category c under spatial node `node` (block_levels():
  /// none), and the ranking of that node's labels within block b of level i >= that.
  std::uint32_t block_finest(std::size_t c, std::uint32_t node) const;
  std::span<const format::NanocubeRankEntry> block_ranking(std::size_t c, std::uint32_t node,
                                                           std::uint32_t level,
                                                           std::uint64_t block) const;
  /// kiln verify's check of the block rankings: each entry equals its label's events in the
  /// block counted from the series, and the entries add up to the node's events in the block.
  bool block_rankings_consistent() const;
  /// The deep check of the rankings (kiln verify): a leaf's ranking adds up to its events, an
  /// inner node's counts each label as its children's rankings do together.
  bool rankings_consistent() const;

  /// Events in series `s` with bins in [b0, b1): two binary searches.
  std::uint64_t series_count(std::uint32_t s, std::int64_t b0, std::int64_t b1) const;

 private:
  template <class F>
  void cover(const ResolvedSelection& r, std::uint32_t node, std::uint32_t level, std::uint64_t x,
             std::uint64_t y, F&& f) const;
  static constexpr std::uint32_t kAnyLabel = 0xFFFFFFFFu;
  template <class F>
  void leaves(const ResolvedSelection& r, std::size_t dim, std::uint32_t node, std::size_t by,
              std::uint32_t label, F&& f, std::uint32_t only = kAnyLabel) const;
  std::uint64_t node_count(const ResolvedSelection& r, std::uint32_t node) const;
  std::uint64_t label_count(const ResolvedSelection& r, std::uint32_t node, std::size_t c,
                            std::uint32_t label) const;
  std::vector<EventLabelCount> threshold_topk(const ResolvedSelection& r, std::size_t c,
                                              std::size_t k, std::span<const std::uint32_t> covered,
                                              TopkTrace& trace) const;
  /// The largest spatial nodes inside the selection's cells (cover's nodes), in Z order.
  std::vector<std::uint32_t> covered_nodes(const ResolvedSelection& r) const;
  void count_labels(const ResolvedSelection& r, std::size_t c, std::uint32_t node,
                    std::vector<std::uint64_t>& counts) const;
  std::vector<EventLabelCount> labels_by_count(std::span<const std::uint64_t> counts, std::size_t c,
                                               std::size_t k) const;

  EventTableView table_;
  EventGrid grid_;
  std::uint32_t root_ = 0;
  std::span<const format::NanocubeNode> nodes_;
  std::span<const format::NanocubeEdge> edges_;
  std::span<const format::NanocubeSeries> series_;
  std::span<const std::uint32_t> series_bins_;
  std::span<const std::uint64_t> series_counts_;
  std::span<const format::NanocubeRankList> rank_lists_;
  std::span<const format::NanocubeRankEntry> rank_entries_;
  std::span<const format::NanocubeBlockIndex> block_index_;
  std::span<const format::NanocubeRankList> block_lists_;
  std::span<const format::NanocubeRankEntry> block_entries_;
  std::uint32_t block_shift_ = 0, block_stride_ = 1, block_levels_ = 0;
  std::vector<std::uint64_t> level_start_;  ///< lists before level i in a node storing all levels
  std::vector<std::uint64_t> dimension_nodes_;
};

/// The reference: every query answered by scanning the mapped table's columns (tests and the
/// benchmark compare the cube with it).
class EventScan final : public EventQueries {
 public:
  /// Computes every row's finest cell once (what a scan would otherwise redo per query).
  EventScan(EventTableView table, EventGrid grid);
  std::uint32_t finest_level() const override { return grid_.max_level; }
  std::int64_t time_bin() const override { return grid_.time_bin; }
  EventSnap snap(const EventSelection& selection) const override;
  std::uint64_t count(const EventSelection& selection) const override;
  std::vector<std::pair<std::int64_t, std::uint64_t>> series(
      const EventSelection& selection, std::int64_t bin_seconds) const override;
  std::vector<EventTileCount> tiles(const EventSelection& selection,
                                    std::uint32_t zoom) const override;
  std::vector<EventLabelCount> topk(const EventSelection& selection, std::string_view by,
                                    std::size_t k) const override;

 private:
  template <class F>
  void scan(const ResolvedSelection& r, F&& f) const;
  EventTableView table_;
  EventGrid grid_;
  std::vector<std::uint32_t> cell_x_, cell_y_;
};

/// Orders topk answers: larger counts first, ties by label; keeps the first k with count > 0.
std::vector<EventLabelCount> top_labels(std::vector<EventLabelCount> all, std::size_t k);
/// The series a request asks for, every count zero: one entry per `bin_seconds` from the
/// snapped start. Throws std::invalid_argument unless bin_seconds is a positive multiple of the
/// grid's bin, or for more than 10^7 bins.
std::vector<std::pair<std::int64_t, std::uint64_t>> empty_series(const EventGrid& grid,
                                                                 const ResolvedSelection& r,
                                                                 std::int64_t bin_seconds);

}  // namespace kiln
