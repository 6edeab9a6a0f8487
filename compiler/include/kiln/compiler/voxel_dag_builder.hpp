// Sparse voxel DAG construction (Kampe, Sintorn, Assarsson 2013) from sorted voxel Morton codes,
// producing the word array of formats/voxel_dag.hpp.
#pragma once

#include <cstdint>
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
