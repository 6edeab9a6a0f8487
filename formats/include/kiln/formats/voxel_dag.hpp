// On-disk layout of the sparse voxel DAG (Kampe, Sintorn, Assarsson 2013): one array of 32-bit
// words. Interior nodes, level by level from the root at word 0: a header word whose low 8 bits
// are the child mask (bit c = octant c, c = x | y << 1 | z << 2 of the child's half), then one
// absolute word index per present child, in octant order. Nodes at level `levels - 3` point at
// leaf masks: 64-bit 4x4x4 blocks stored as two words (low first), bit i = the voxel whose
// Morton index inside the block is i. Identical subtrees are stored once.
#pragma once

#include <cstdint>

#include "kiln/formats/container.hpp"
#include "kiln/formats/voxel_grid.hpp"

namespace kiln::format {

inline constexpr std::uint32_t kSectionDagWords = fourcc('D', 'A', 'G', 'W');
inline constexpr std::uint32_t kSectionVoxelCodes = fourcc('V', 'X', 'M', 'C');
inline constexpr std::uint32_t kSectionVoxelNormals = fourcc('V', 'X', 'N', 'O');

}  // namespace kiln::format
