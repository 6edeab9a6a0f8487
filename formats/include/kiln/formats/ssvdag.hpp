// On-disk layout of the symmetry-aware sparse voxel DAG (Villanueva, Marton, Gobbetti 2016):
// subtrees equal up to mirroring along x, y and z are stored once, and every child pointer
// carries the three mirror bits that turn the stored subtree into the one it stands for.
//
// SSVN, uint16 words: the interior levels, root (level 0) first, each level's nodes contiguous
// from its first word (VoxelSsvdagDesc.level_stats). A node is a header word, low byte the child
// mask (bit c = octant c, c = x | y << 1 | z << 2), high byte the wide mask (bit c: child c's
// pointer takes two words; a subset of the child mask), then one pointer per present child in
// octant order: 1 word (narrow) or 2 words (wide, low word first), value = offset << 3 | mirror,
// mirror bit a = mirror along axis a (x, y, z). Offset = the child's first word counted from its
// level's first word, or, from the last interior level, the index of a leaf in SSVL. Nodes of a
// level are ordered by how many pointers reach them, most first, so that most pointers are
// narrow (the paper's variable-size pointers).
// SSVL, uint64: 4x4x4 leaf masks, bit i = the voxel whose Morton index inside the block is i.
#pragma once

#include <cstdint>

#include "kiln/formats/container.hpp"

namespace kiln::format {

inline constexpr std::uint32_t kSectionSsvdagNodes = fourcc('S', 'S', 'V', 'N');
inline constexpr std::uint32_t kSectionSsvdagLeaves = fourcc('S', 'S', 'V', 'L');

/// A narrow pointer holds offsets below 2^13, a wide one below 2^29.
inline constexpr std::uint32_t kSsvdagNarrowOffsets = 1u << 13;
inline constexpr std::uint32_t kSsvdagWideOffsets = 1u << 29;

/// The child mask (bit c = octant c) of a node mirrored by `mirror`: octant c moves to c ^ mirror.
constexpr std::uint32_t ssvdag_mirror_mask(std::uint32_t mask, std::uint32_t mirror) {
  if (mirror & 1) mask = (mask & 0x55) << 1 | (mask >> 1 & 0x55);
  if (mirror & 2) mask = (mask & 0x33) << 2 | (mask >> 2 & 0x33);
  if (mirror & 4) mask = (mask & 0x0F) << 4 | (mask >> 4 & 0x0F);
  return mask;
}

/// The Morton index bits that a mirror flips inside a 4x4x4 block (x -> 3 - x flips both x bits).
constexpr std::uint32_t ssvdag_leaf_flip(std::uint32_t mirror) {
  return (mirror & 1 ? 9u : 0u) | (mirror & 2 ? 18u : 0u) | (mirror & 4 ? 36u : 0u);
}

/// A 4x4x4 leaf mask mirrored by `mirror`: bit i moves to bit i ^ ssvdag_leaf_flip(mirror).
constexpr std::uint64_t ssvdag_mirror_leaf(std::uint64_t leaf, std::uint32_t mirror) {
  constexpr std::uint64_t kLow[6] = {0x5555555555555555ull, 0x3333333333333333ull,
                                     0x0F0F0F0F0F0F0F0Full, 0x00FF00FF00FF00FFull,
                                     0x0000FFFF0000FFFFull, 0x00000000FFFFFFFFull};
  const std::uint32_t flip = ssvdag_leaf_flip(mirror);
  for (std::uint32_t k = 0; k < 6; ++k)
    if (flip >> k & 1) leaf = (leaf & kLow[k]) << (1u << k) | (leaf >> (1u << k) & kLow[k]);
  return leaf;
}

}  // namespace kiln::format
