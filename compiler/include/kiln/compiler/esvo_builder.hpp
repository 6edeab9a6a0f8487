// Efficient Sparse Voxel Octree construction (Laine & Karras 2010), top down from the triangles:
// a voxel stops subdividing once its contour approximates the surface within the error bound,
// so depth adapts to the geometry. Output is the word layout of formats/esvo.hpp.
#pragma once

#include <cstdint>
#include <vector>

#include "kiln/compiler/scene.hpp"
#include "kiln/compiler/voxelizer.hpp"
#include "kiln/formats/esvo.hpp"

namespace kiln {

struct EsvoBuildOptions {
  std::uint32_t resolution = 1024;  // the finest level (format::is_valid_voxel_resolution)
  bool contours = true;
  // The bound, in finest voxels, on the distance from any point of a leaf's region (so any hit)
  // to a triangle; at least sqrt(3), what a finest cube guarantees. A coarser voxel becomes a
  // leaf when every finest cell its contour slab meets lies within `reach` cells, along the
  // slab's dominant axis, of a cell a triangle touches: reach is the largest r with
  // sqrt(2 + (r + 1)^2) <= contour_error (r = 0 at sqrt(3); r = 1 at the default).
  double contour_error = 2.45;
  unsigned threads = 0;  // never changes the result
  // Bytes the build may hold at once (0: default_memory_budget()); sizes the cubes voxelized one
  // at a time, so peak memory follows the ESVO's own size. Never changes the result.
  std::uint64_t memory_budget = 0;
  // The side of those cubes (a power of two; at least 64, or the resolution for the whole grid at
  // once); 0: from the budget. Never changes the result (tests compare the two).
  std::uint32_t cube_side = 0;
  bool progress = false;  // a line on stderr as cubes finish
};

// The bound the build guarantees for these options: sqrt(2 + (reach + 1)^2) finest voxels.
// Throws std::invalid_argument when contour_error is below sqrt(3) or not finite.
double esvo_error_bound(const EsvoBuildOptions& options);

struct EsvoLevelStats {
  std::uint64_t descriptors = 0, voxels = 0, leaves = 0, contours = 0;
};

struct FlatEsvo {
  VoxelGrid grid;
  std::uint32_t levels = 0;
  std::vector<std::uint32_t> words;
  std::vector<std::uint32_t> pages;
  std::vector<format::EsvoBlockInfo> blocks;
  std::vector<std::uint32_t> normals;  // octahedral, one per voxel
  std::vector<std::uint32_t> colors;   // RGBA8, one per voxel; empty when the scene has none
  std::vector<EsvoLevelStats> level_stats;
  std::uint64_t descriptor_count = 0, voxel_count = 0, leaf_count = 0, contour_count = 0,
                far_pointer_count = 0;
  std::uint32_t max_depth = 0;
  std::uint64_t hierarchy_bytes = 0, contour_bytes = 0, attachment_bytes = 0;
};

// Throws std::invalid_argument for a resolution outside the voxel grids' range or a bad
// contour_error.
FlatEsvo build_esvo(const Scene& scene, const EsvoBuildOptions& options);

}  // namespace kiln
