// k-d tree over points (kNN and radius searches) producing the mapped layout of
// formats/point_tree.hpp.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "kiln/formats/geometry.hpp"
#include "kiln/formats/point_tree.hpp"

namespace kiln {

enum class PointSplitRule {
  kMedian,           // balanced: the median on the widest axis
  kSlidingMidpoint,  // the middle of the points' extent on the widest axis (Maneewongvatana and
                     // Mount 1999); cells stay fat, which suits clustered scans
};
std::string to_string(PointSplitRule rule);

struct PointTreeBuildOptions {
  PointSplitRule split = PointSplitRule::kSlidingMidpoint;
  std::uint32_t max_leaf_size = 10;  // nanoflann's default
  unsigned threads = 0;              // never changes the result
};

inline constexpr std::uint32_t kMaxPointLeafSize = 4096;

struct PointTreeStatistics {
  std::uint64_t node_count = 0, leaf_count = 0, point_count = 0;
  std::uint32_t max_depth = 0, largest_leaf = 0;
  double bytes_per_point = 0;  // nodes + points + ids
};

struct FlatPointTree {
  format::Box3f bounds;  // of every point
  std::vector<format::PointNode> nodes;
  std::vector<format::Float3> points;  // leaf order
  std::vector<std::uint32_t> ids;      // index into the input per point, leaf order
  PointTreeStatistics stats;
};

// Every input point goes into exactly one leaf, the ids in a leaf ascending. Points must be
// finite. Throws std::invalid_argument on an empty input or a bad leaf size.
FlatPointTree build_point_tree(std::span<const format::Float3> points,
                               const PointTreeBuildOptions& options);

}  // namespace kiln
