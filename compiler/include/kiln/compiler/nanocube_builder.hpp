// The nanocube builder (Lins, Klosowski & Scheidegger 2013): a quadtree over Web-Mercator cells,
// then one flat tree per category, then per leaf a cumulative series over time bins; with
// sharing, a node whose events are exactly a child's reuses that child's content, and a node
// whose events all come from one part already built links to it (the paper's shared links).
#pragma once

#include <cstdint>
#include <vector>

#include "kiln/compiler/event_table.hpp"
#include "kiln/formats/nanocube.hpp"

namespace kiln {

struct NanocubeOptions {
  std::uint32_t max_level = 20;  ///< finest quadtree level (<= format::kNanocubeMaxLevel)
  std::int64_t time_bin = 3600;  ///< seconds per bin
  bool sharing = true;           ///< false: every content copied (same answers, bigger)
  /// Topkube's rankings per block of time bins are stored for a spatial node and category when
  /// the node holds at least this many events and labels (smaller ones are counted fast).
  std::uint64_t block_min_events = 1024;
  std::uint32_t block_min_labels = 32;
  /// Bytes of block rankings allowed per event of the node and category: the finest levels
  /// are dropped until the node's block rankings fit.
  double block_bytes_per_event = 6.0;
  std::uint32_t block_shift = 1,
                block_stride = 2;  ///< level i: blocks of 2^(shift + stride i) bins
};

/// The flattened cube (docs/FORMAT.md, "Nanocube").
struct NanocubeData {
  std::vector<format::NanocubeNode> nodes;
  std::vector<format::NanocubeEdge> edges;
  std::vector<format::NanocubeSeries> series;
  std::vector<std::uint32_t> series_bins;
  std::vector<std::uint64_t> series_counts;
  std::vector<format::NanocubeRankList> rank_lists;  ///< per category, per spatial node
  std::vector<format::NanocubeRankEntry> rank_entries;
  std::vector<format::NanocubeBlockIndex> block_index;  ///< per category, per spatial node
  std::vector<format::NanocubeRankList> block_lists;
  std::vector<format::NanocubeRankEntry> block_entries;
  std::uint32_t block_shift = 0, block_stride = 1, block_levels = 0;
  std::vector<std::uint64_t> dimension_nodes;  ///< where each dimension starts, + the end
  std::uint32_t root = 0;
  std::uint64_t shared_content_links = 0, shared_child_links = 0;
  std::int64_t time_origin = 0;
  std::uint32_t bin_count = 0;

  std::uint64_t bytes() const {
    return nodes.size() * sizeof(nodes[0]) + edges.size() * sizeof(edges[0]) +
           series.size() * sizeof(series[0]) + series_bins.size() * 4 + series_counts.size() * 8 +
           rank_lists.size() * sizeof(rank_lists[0]) +
           rank_entries.size() * sizeof(rank_entries[0]) + block_bytes();
  }
  std::uint64_t block_bytes() const {
    return block_index.size() * sizeof(format::NanocubeBlockIndex) +
           block_lists.size() * sizeof(format::NanocubeRankList) +
           block_entries.size() * sizeof(format::NanocubeRankEntry);
  }
};

/// Builds the cube over every row of `table`. Deterministic (single pass, no hashing). Throws
/// std::invalid_argument when the table's time span needs more than 2^32 bins.
NanocubeData build_nanocube(const EventTable& table, const NanocubeOptions& options);

}  // namespace kiln
