// Sparse voxel DAG construction (Kampe, Sintorn, Assarsson 2013) from sorted voxel Morton codes,
// producing the word array of formats/voxel_dag.hpp.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "kiln/compiler/voxelizer.hpp"

namespace kiln {

struct VoxelDagLevelStats {
  std::uint64_t svo_nodes = 0, dag_nodes = 0, bytes = 0, first_word = 0;
};

struct FlatVoxelDag {
  std::uint32_t levels = 0;  // log2(resolution)
  std::vector<std::uint32_t> words;
  std::uint64_t leaf_first_word = 0;
  std::vector<VoxelDagLevelStats> level_stats;  // levels - 1 entries: 0 .. levels - 2 (leaves)
  std::uint64_t voxel_count = 0, svo_bytes = 0, dag_bytes = 0;
};

// Bottom up: 4x4x4 leaf masks first, then level by level nodes with identical child masks and
// identical child pointers merge (hash, then exact compare). Node ids follow first occurrence in
// Morton order, so the words depend on the codes alone. `codes` must be ascending, unique,
// non-empty and below resolution^3.
FlatVoxelDag build_voxel_dag(std::span<const std::uint64_t> codes, std::uint32_t resolution);
// The same from 4x4x4 blocks (keys ascending, masks non-zero), as solid_leaves makes them.
FlatVoxelDag build_voxel_dag(const VoxelLeaves& leaves, std::uint32_t resolution);

/// The out-of-core build (Kampe et al. 2013, section 4): the grid is cut into cubes, visited in
/// Morton order; each cube's triangles are binned from its parent's (never the whole list per
/// cube), its surface voxels made as 4x4x4 leaves (voxelize_surface_leaves), reduced to a sub-DAG
/// through one table of unique nodes per level shared by all cubes, and the nodes above the
/// cubes built from their roots. A level's ids follow first occurrence in Morton order whatever
/// the cut, so the words equal build_voxel_dag's of the whole grid's surface voxels, byte for
/// byte, for any budget, cube side and thread count. Memory: the unique nodes (the DAG) plus one
/// cube's leaves and its voxelizer's working set, plus the triangle lists along one path.
struct OutOfCoreDagOptions {
  /// Bytes the build may hold; a cube is split while its estimated working set (a bound on its
  /// surface voxels, 32 bytes each, plus its voxelizer's bins) passes a quarter of it: the rest
  /// is left to the scene, the unique nodes and the triangle lists. 0: default_memory_budget().
  std::uint64_t memory_budget = 0;
  /// Forces every cube to this side (a power of two >= 4, <= the resolution); 0: from the budget.
  std::uint32_t cube_side = 0;
  unsigned threads = 0;  ///< never changes the result
  /// Called after each cube with (cubes done, cubes planned, share of estimated voxels done in
  /// [0, 1]); when set, a first pass plans the cubes (bins twice) so the total is known.
  std::function<void(std::uint64_t, std::uint64_t, double)> progress;
};

struct OutOfCoreDagStats {
  std::uint64_t cubes = 0;          ///< cubes voxelized (non-empty triangle lists)
  std::uint32_t smallest_side = 0;  ///< of those cubes
  std::uint32_t largest_side = 0;
  std::uint64_t largest_cube_voxels = 0;  ///< most surface voxels of one cube
};

/// The surface voxels' DAG of `scene` on `grid` (resolution up to format::kVoxelMaxResolution),
/// built out of core. Throws std::invalid_argument when no voxel is set or a bad cube side,
/// std::length_error when the DAG would pass 2^32 words.
FlatVoxelDag build_voxel_dag_out_of_core(const Scene& scene, const VoxelGrid& grid,
                                         const OutOfCoreDagOptions& options,
                                         OutOfCoreDagStats* stats = nullptr);

// Each level's first word, as VoxelDagView takes them.
inline std::vector<std::uint64_t> level_first_words(const FlatVoxelDag& dag) {
  std::vector<std::uint64_t> firsts;
  for (const auto& level : dag.level_stats) firsts.push_back(level.first_word);
  return firsts;
}

// Every voxel of the DAG as sorted Morton codes (the inverse, for tests and tools).
std::vector<std::uint64_t> expand_voxel_dag(std::span<const std::uint32_t> words,
                                            std::uint32_t levels);

}  // namespace kiln
