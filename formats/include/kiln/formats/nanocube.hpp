// The nanocube's flattened layout (docs/FORMAT.md, "Nanocube"): every dimension's nodes in one
// array (space first, then each category), child edges sorted by key, and per leaf of the last
// dimension a sparse cumulative count series over time bins.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "kiln/formats/container.hpp"

namespace kiln::format {

inline constexpr std::uint32_t kSectionNanocubeNodes = fourcc('N', 'C', 'N', 'D');
inline constexpr std::uint32_t kSectionNanocubeEdges = fourcc('N', 'C', 'E', 'D');
inline constexpr std::uint32_t kSectionNanocubeSeries = fourcc('N', 'C', 'S', 'R');
inline constexpr std::uint32_t kSectionNanocubeSeriesBins = fourcc('N', 'C', 'T', 'B');
inline constexpr std::uint32_t kSectionNanocubeSeriesCounts = fourcc('N', 'C', 'T', 'C');
inline constexpr std::uint32_t kSectionNanocubeRankLists = fourcc('N', 'C', 'R', 'L');
inline constexpr std::uint32_t kSectionNanocubeRankEntries = fourcc('N', 'C', 'R', 'E');
inline constexpr std::uint32_t kSectionNanocubeBlockIndex = fourcc('N', 'C', 'B', 'I');
inline constexpr std::uint32_t kSectionNanocubeBlockLists = fourcc('N', 'C', 'B', 'L');
inline constexpr std::uint32_t kSectionNanocubeBlockEntries = fourcc('N', 'C', 'B', 'E');

/// The deepest quadtree the format allows (cells of 2^30 per axis fit uint32 keys).
inline constexpr std::uint32_t kNanocubeMaxLevel = 30;

/// Whether a cube's space and time grid is one the format allows: bins of 1 s .. 2^40 s, an
/// origin on a bin boundary within +-2^60 s, and origin + bin_count * time_bin within 2^61 s, so
/// no time computed from the grid overflows int64.
inline bool nanocube_grid_valid(std::uint32_t max_level, std::int64_t time_bin,
                                std::int64_t time_origin, std::uint32_t bin_count) {
  constexpr std::int64_t kMaxOrigin = std::int64_t(1) << 60;
  return max_level <= kNanocubeMaxLevel && time_bin > 0 && time_bin <= (std::int64_t(1) << 40) &&
         time_origin % time_bin == 0 && time_origin >= -kMaxOrigin && time_origin <= kMaxOrigin &&
         std::int64_t(bin_count) <= kMaxOrigin / time_bin;
}

/// A node of one dimension. Its children are edges first_edge .. first_edge + edge_count - 1,
/// keys strictly increasing, each child's index below the node's own (children are written
/// first, so the graph is acyclic). `content` is a node of the next dimension (its root over
/// this node's events) or, in the last dimension, a series index. A shared content link is a
/// content equal to a child's; a shared child link points into a structure built earlier.
struct NanocubeNode {
  std::uint64_t first_edge;
  std::uint32_t edge_count;
  std::uint32_t content;
};
static_assert(sizeof(NanocubeNode) == 16);

/// A child edge: key = quadrant (x bit | y bit << 1) in space, the label code in a category.
struct NanocubeEdge {
  std::uint32_t key;
  std::uint32_t node;
};
static_assert(sizeof(NanocubeEdge) == 8);

/// Entries first .. first + count - 1 of the series arrays: bins strictly increasing, counts
/// cumulative (events in bins <= that bin), so events in [b0, b1) are two binary searches.
struct NanocubeSeries {
  std::uint64_t first;
  std::uint64_t count;
};
static_assert(sizeof(NanocubeSeries) == 16);

/// Topkube's stored ranking (Miranda et al. 2018) of one category over one spatial node's
/// events: rank entries first .. first + count - 1, counts non-increasing, ties by label code.
/// List `c * spatial_nodes + n` ranks category c under spatial node n; a node with one child
/// shares its child's entries.
struct NanocubeRankList {
  std::uint64_t first;
  std::uint32_t count;
  std::uint32_t reserved;  ///< 0
};
static_assert(sizeof(NanocubeRankList) == 16);

/// A label code and how many of the node's events (over all time) carry it.
struct NanocubeRankEntry {
  std::uint32_t label;
  std::uint32_t count;
};
static_assert(sizeof(NanocubeRankEntry) == 8);

/// Topkube's rankings over time: per category c and spatial node n (at c * spatial_nodes + n),
/// the node's labels ranked per block of time bins. Block level i (0 .. levels - 1) has blocks of
/// 2^(shift + stride * i) bins, block b covering bins [b * size, min((b + 1) * size, bin_count)).
/// The node stores levels `finest` .. levels - 1 (finest = levels: none), level after level, each
/// level's blocks in order, as NanocubeRankLists into the block entries from `first_list`.
struct NanocubeBlockIndex {
  std::uint64_t first_list;
  std::uint32_t finest;
  std::uint32_t reserved;  ///< 0
};
static_assert(sizeof(NanocubeBlockIndex) == 16);

/// The block levels a cube may have: at most 24, sizes up to 2^32 bins.
inline constexpr std::uint32_t kNanocubeMaxBlockLevels = 24;
inline bool nanocube_blocks_valid(std::uint32_t shift, std::uint32_t stride, std::uint32_t levels) {
  return levels <= kNanocubeMaxBlockLevels && stride >= 1 && stride <= 8 && shift <= 32 &&
         (levels == 0 || shift + std::uint64_t(stride) * (levels - 1) <= 32);
}
/// Bins per block at level i, and blocks at that level over bin_count bins.
inline std::uint64_t nanocube_block_size(std::uint32_t shift, std::uint32_t stride,
                                         std::uint32_t i) {
  return std::uint64_t(1) << (shift + stride * i);
}
inline std::uint64_t nanocube_block_count(std::uint32_t bin_count, std::uint64_t size) {
  return (std::uint64_t(bin_count) + size - 1) / size;
}

/// Web-Mercator cells at `level` (x east from -180 degrees, y south from +85.0511 degrees):
/// the cell of a longitude or latitude, clamped to the grid (NaN goes to cell 0), and a cell
/// edge's coordinate. The nanocube, its queries and the brute-force scan all use these.
inline std::uint32_t mercator_cell_x(double lon, std::uint32_t level) {
  const double n = std::ldexp(1.0, int(level));
  const double x = (lon + 180.0) / 360.0 * n;
  if (!(x > 0)) return 0;
  return std::uint32_t(std::min(std::floor(x), n - 1));
}
inline std::uint32_t mercator_cell_y(double lat, std::uint32_t level) {
  constexpr double kPi = 3.14159265358979323846, kMaxLat = 85.0511287798066;
  const double n = std::ldexp(1.0, int(level));
  const double clamped = std::clamp(lat, -kMaxLat, kMaxLat);
  const double y = (1.0 - std::asinh(std::tan(clamped * kPi / 180.0)) / kPi) / 2.0 * n;
  if (!(y > 0)) return 0;
  return std::uint32_t(std::min(std::floor(y), n - 1));
}
inline double mercator_lon(std::uint64_t x, std::uint32_t level) {
  return std::ldexp(double(x), -int(level)) * 360.0 - 180.0;
}
inline double mercator_lat(std::uint64_t y, std::uint32_t level) {
  constexpr double kPi = 3.14159265358979323846;
  return std::atan(std::sinh(kPi * (1.0 - 2.0 * std::ldexp(double(y), -int(level))))) * 180.0 / kPi;
}

}  // namespace kiln::format
