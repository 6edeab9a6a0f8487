// On-disk layout of the symmetry-aware sparse voxel DAG (Villanueva, Marton, Gobbetti 2016):
// subtrees equal up to mirroring along x, y and z are stored once, and every child pointer
// carries the three mirror bits that turn the stored subtree into the one it stands for.
//
// SSVR, uint16 words: the interior levels, root (level 0) first, each level's nodes contiguous
// from its first word (VoxelSsvdagDesc.level_stats). A node is a header word, low byte the child
// mask (bit c = octant c, c = x | y << 1 | z << 2), high byte the wide mask (bit c: child c's
// pointer takes two words; a subset of the child mask), then one pointer per present child in
// octant order: 1 word (narrow) or 2 words (wide, low word first), value = x << 3 | mirror,
// mirror bit a = mirror along axis a (x, y, z). x names the child's first word counted from its
// level's first word, or, from the last interior level, the index of a leaf in SSVL:
// - wide: x itself (below 2^29);
// - narrow into the leaves: x itself (below 2^13);
// - narrow into an interior level: x below 2^12 is the offset itself (the level's first 4096
//   words hold its most referenced nodes); x from 2^12 is relative, offset = base + x - 6144
//   (-2048..2047 around base), base = the offset of the node's first wide pointer (lowest bit of
//   the wide mask), which such a node must have. Nodes that are not among the most referenced
//   follow in the order of their first reference, so a node's children mostly lie side by side.
// SSVL, uint64: 4x4x4 leaf masks, bit i = the voxel whose Morton index inside the block is i.
// SSVN (the same words with every narrow pointer absolute, written before 2026-11-27) is no
// longer read: a reader refuses it with a message to rebuild.
#pragma once

#include <bit>
#include <cstdint>

#include "kiln/formats/container.hpp"

namespace kiln::format {

inline constexpr std::uint32_t kSectionSsvdagNodes = fourcc('S', 'S', 'V', 'R');
/// The node words before relative pointers: refused with a message to rebuild.
inline constexpr std::uint32_t kSectionSsvdagNodesAbsolute = fourcc('S', 'S', 'V', 'N');
inline constexpr std::uint32_t kSectionSsvdagLeaves = fourcc('S', 'S', 'V', 'L');

/// A narrow pointer into the leaves holds indices below 2^13, a wide one offsets below 2^29.
inline constexpr std::uint32_t kSsvdagNarrowOffsets = 1u << 13;
inline constexpr std::uint32_t kSsvdagWideOffsets = 1u << 29;
/// A narrow pointer into an interior level: absolute below 2^12, else relative to the node's
/// base within [-kSsvdagRelativeReach, kSsvdagRelativeReach).
inline constexpr std::uint32_t kSsvdagAbsoluteOffsets = 1u << 12;
inline constexpr std::int64_t kSsvdagRelativeReach = 1 << 11;
/// What ssvdag_child returns for a relative pointer in a node without a wide pointer.
inline constexpr std::uint64_t kSsvdagNoBase = ~std::uint64_t(0);

/// The narrow pointer's x for a child at `offset`, relative to `base` (|offset - base| in reach).
constexpr std::uint32_t ssvdag_relative_x(std::uint64_t offset, std::uint64_t base) {
  return std::uint32_t(std::int64_t(offset) - std::int64_t(base) + kSsvdagAbsoluteOffsets +
                       kSsvdagRelativeReach);
}

/// Child `stored` (present in the header) of the node whose header is words[0]: its offset in
/// the next level (or leaf index, when `to_leaves`) and its pointer's mirror. A relative pointer
/// in a node without a wide pointer gives kSsvdagNoBase; an offset below the level's start wraps
/// to a value past any level. `words` must hold the whole node.
inline std::uint64_t ssvdag_child(const std::uint16_t* words, std::uint32_t stored, bool to_leaves,
                                  std::uint32_t& mirror) {
  const std::uint32_t header = words[0], mask = header & 0xFF, wide = header >> 8;
  const std::uint32_t before = (1u << stored) - 1;
  const std::uint32_t at = 1 + std::popcount(mask & before) + std::popcount(wide & before);
  std::uint32_t value = words[at];
  const bool is_wide = wide >> stored & 1;
  if (is_wide) value |= std::uint32_t(words[at + 1]) << 16;
  mirror = value & 7;
  const std::uint64_t x = value >> 3;
  if (is_wide || to_leaves || x < kSsvdagAbsoluteOffsets) return x;
  if (wide == 0) return kSsvdagNoBase;
  const std::uint32_t first = std::countr_zero(wide);
  const std::uint32_t base_at = 1 + std::popcount(mask & ((1u << first) - 1));
  const std::uint64_t base = (words[base_at] | std::uint32_t(words[base_at + 1]) << 16) >> 3;
  return base + x - std::uint64_t(kSsvdagAbsoluteOffsets + kSsvdagRelativeReach);
}

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
