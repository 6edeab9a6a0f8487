// Octree builder over triangles: cells split at their centre into eight, each triangle
// referenced in every child cell its surface meets (exact separating-axis test), producing the
// mapped layout of formats/octree.hpp.
#pragma once

#include <cstdint>
#include <vector>

#include "kiln/compiler/scene.hpp"
#include "kiln/formats/geometry.hpp"
#include "kiln/formats/octree.hpp"

namespace kiln {

struct OctreeBuildOptions {
  std::uint32_t leaf_size = 8;   // a cell with at most this many triangles stays a leaf
  std::uint32_t max_depth = 16;  // no leaf deeper (root = 0); at most kOctreeMaxDepth
  // At most this many references per triangle on average: the level that would pass it is not
  // split (bounds memory when large triangles cross each other everywhere).
  std::uint32_t reference_budget = 32;
  unsigned threads = 0;  // never changes the result
};

struct OctreeStatistics {
  std::uint64_t node_count = 0, leaf_count = 0, empty_cell_count = 0, reference_count = 0;
  std::uint64_t depth_limited_leaves = 0, stalled_leaves = 0;
  std::uint32_t max_depth = 0, largest_leaf = 0;
  bool budget_reached = false;  // a level was left unsplit by the reference budget
  double references_per_triangle = 0, bytes_per_triangle = 0;
};

struct FlatOctree {
  format::Box3f bounds;                        // the root cell
  std::vector<format::OctreeNode> nodes;       // breadth first
  std::vector<std::uint32_t> prim_ids;         // leaf references in node order
  std::vector<format::RayTriangle> triangles;  // every triangle's corners, by primitive id
  OctreeStatistics stats;
};

/// The root cell: the scene's bounds made cubic (every edge the longest extent, from the
/// bounds' minimum corner, rounded up so it still holds the scene). Cubic cells stay cubic at
/// every depth, so a flat scene never gets zero-width cells and a cell's size is one number.
format::Box3f octree_root_cell(const format::Box3f& scene_bounds);

/// Throws std::runtime_error on an empty scene, or when the tree outgrows the layout (32-bit
/// node and reference indices, 24-bit leaf reference counts).
FlatOctree build_octree(const Scene& scene, const OctreeBuildOptions& options);

}  // namespace kiln
