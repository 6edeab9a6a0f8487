// `kiln query --op range|knn2d|radius2d`: range and neighbour queries on a blob's 2D point
// table, answered by whichever structure has Point2Queries (query_points2d.cpp).
#pragma once

#include <algorithm>
#include <cstdint>
#include <span>
#include <string>

namespace kiln::cli {

struct Points2dQueryArgs {
  std::string blob, op, in, out, accel;
  unsigned k = 1;
  double radius = 0;
  unsigned threads = 0;
};

/// Point index -> table row: the feature owning the point (the identity without
/// feature_points).
struct RowOf {
  std::span<const std::uint64_t> feature_points;
  std::uint64_t operator()(std::uint32_t point) const {
    if (feature_points.empty()) return point;
    const auto it = std::upper_bound(feature_points.begin(), feature_points.end(), point);
    return std::uint64_t(it - feature_points.begin()) - 1;
  }
};

/// Whether `op` is one of the 2D point-table operations.
bool is_points2d_op(const std::string& op);
/// Runs the query; one line on stderr and exit status 1 on any error.
int run_points2d_query(const Points2dQueryArgs& args);

}  // namespace kiln::cli
