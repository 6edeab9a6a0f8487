// Bucket PR quadtree over 2D points (range, k nearest, radius) producing the mapped layout of
// formats/quadtree.hpp.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "kiln/formats/quadtree.hpp"
#include "kiln/formats/vector.hpp"

namespace kiln {

struct QuadtreeBuildOptions {
  std::uint32_t bucket_size = 32;  // most points per leaf, except at max_depth (docs/BENCHMARKS.md)
  std::uint32_t max_depth = 32;    // deepest leaf level (root = 0); coincident points stop there
  unsigned threads = 0;            // never changes the result
};

inline constexpr std::uint32_t kMaxQuadBucketSize = 4096;

/// Per level of the tree (root = 0): nodes, leaves among them, and points in those leaves.
struct QuadLevel {
  std::uint64_t nodes = 0, leaves = 0, leaf_points = 0;
};

struct QuadtreeStatistics {
  std::uint64_t node_count = 0, leaf_count = 0, point_count = 0;
  std::uint32_t depth = 0, largest_bucket = 0;
  double bytes_per_point = 0;  // nodes + points + ids
};

struct FlatQuadtree {
  format::Box2d root;    // the root cell: a square with `bounds.min` as its corner
  format::Box2d bounds;  // of every point
  std::vector<format::QuadNode> nodes;
  std::vector<format::Double2> points;  // leaf order
  std::vector<std::uint32_t> ids;       // index into the input per point, leaf order
  QuadtreeStatistics stats;
};

/// Every input point goes into exactly one leaf; a leaf's ids ascend. A cell with more than
/// `bucket_size` points splits into its four quadrants unless it is at `max_depth` or its points
/// all coincide. Throws std::invalid_argument on an empty input, a non-finite point, or an
/// option out of range; std::length_error past 2^32 points or 2^29 nodes.
FlatQuadtree build_quadtree(std::span<const format::Double2> points,
                            const QuadtreeBuildOptions& options);

}  // namespace kiln
