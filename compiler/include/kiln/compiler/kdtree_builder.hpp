// SAH k-d tree builder (Wald & Havran 2006, O(N log N) with perfect splits) producing the
// mapped layout of formats/kdtree.hpp.
#pragma once

#include <cstdint>
#include <vector>

#include "kiln/compiler/scene.hpp"
#include "kiln/compiler/triangle_clip.hpp"  // clip_triangle_to_box: perfect splits
#include "kiln/formats/geometry.hpp"
#include "kiln/formats/kdtree.hpp"

namespace kiln {

struct KdTreeBuildOptions {
  // Wald & Havran's constants: K_T = 15, K_I = 20, and a 20% bonus for cutting off empty space.
  float traversal_cost = 15.0f;
  float intersection_cost = 20.0f;
  float empty_bonus = 0.2f;
  unsigned threads = 0;  // never changes the result
};

struct KdTreeStatistics {
  std::uint64_t node_count = 0, leaf_count = 0, empty_leaf_count = 0, reference_count = 0;
  std::uint32_t depth_limit = 0, max_depth = 0, largest_leaf = 0;
  double references_per_triangle = 0, sah_cost = 0, bytes_per_triangle = 0;
};

struct FlatKdTree {
  format::Box3f bounds;  // the root cell
  std::vector<format::KdNode> nodes;
  std::vector<std::uint32_t> prim_ids;         // leaf references in leaf order
  std::vector<format::RayTriangle> triangles;  // every triangle's corners, by primitive id
  KdTreeStatistics stats;
};

// The most levels (the root is level 1) a tree over n triangles may have: pbrt's safety cap
// 8 + 1.3 log2(n), at most kKdMaxDepth - 1.
std::uint32_t kd_depth_limit(std::size_t triangle_count);

FlatKdTree build_kdtree(const Scene& scene, const KdTreeBuildOptions& options);

}  // namespace kiln
