// On-disk layout of the Efficient Sparse Voxel Octree (Laine & Karras 2010), which is also its
// runtime layout: the runtime casts rays on the mapped words. docs/FORMAT.md §18 has the whole
// picture; in short:
//
// ESVW, uint32 words. A child descriptor is two words at an even index:
//   word 0: bits 31..17 child pointer (15 bits), bit 16 far, bits 15..8 valid mask,
//           bits 7..0 non-leaf mask (the paper's "leaf mask": set = the child has a descriptor)
//   word 1: bits 31..8 contour pointer (24 bits), bits 7..0 contour mask
// Bit c of a mask is octant c = x | y << 1 | z << 2 of the child's half of the node.
// The descriptors of a node's non-leaf children are contiguous (octant order) at
//   near: descriptor word + 2 * pointer;   far: descriptor word + ESVW[descriptor word + pointer].
// The contour pointer names the node's voxel run at descriptor word + pointer: one word holding
// the attachment index of its first valid child (relative to its block), then one contour word
// per set bit of the contour mask, in octant order. The root descriptor is at word 0.
//
// ESVP, one uint32 per 8 KiB page of ESVW (2048 words): the block holding the page's first word.
// ESVB, EsvoBlockInfo per block, ascending first_word: a block is a run of words built as one
// subtree; its voxels' attachments start at attachment_base.
// ESVN, uint32 octahedral normal per voxel (formats/voxel_grid.hpp): the attachment, indexed
//   block.attachment_base + run word 0 + popcount(valid mask below the child's octant).
// ESVC, RGBA8 colour per voxel (r in the low byte), indexed as ESVN: only when the input had
// vertex or material colours.
#pragma once

#include <bit>
#include <cstdint>
#include <cstdlib>

#include "kiln/formats/container.hpp"
#include "kiln/formats/voxel_grid.hpp"

namespace kiln::format {

inline constexpr std::uint32_t kSectionEsvoWords = fourcc('E', 'S', 'V', 'W');
inline constexpr std::uint32_t kSectionEsvoPages = fourcc('E', 'S', 'V', 'P');
inline constexpr std::uint32_t kSectionEsvoBlocks = fourcc('E', 'S', 'V', 'B');
inline constexpr std::uint32_t kSectionEsvoNormals = fourcc('E', 'S', 'V', 'N');
inline constexpr std::uint32_t kSectionEsvoColors = fourcc('E', 'S', 'V', 'C');

inline constexpr std::uint32_t kEsvoPageWords = 2048;  // 8 KiB, as in the paper
inline constexpr std::uint32_t kEsvoNearPointerMax = (1u << 15) - 1;
inline constexpr std::uint32_t kEsvoContourPointerMax = (1u << 24) - 1;

struct EsvoBlockInfo {
  std::uint64_t first_word;
  std::uint64_t attachment_base;
};
static_assert(sizeof(EsvoBlockInfo) == 16);

struct EsvoDescriptor {
  std::uint32_t child_pointer;  // 15 bits
  bool far;
  std::uint8_t valid, non_leaf;   // masks
  std::uint32_t contour_pointer;  // 24 bits
  std::uint8_t contour_mask;
};

inline EsvoDescriptor decode_descriptor(std::uint32_t w0, std::uint32_t w1) {
  return {w0 >> 17, (w0 >> 16 & 1) != 0, std::uint8_t(w0 >> 8), std::uint8_t(w0),
          w1 >> 8,  std::uint8_t(w1)};
}
inline void encode_descriptor(const EsvoDescriptor& d, std::uint32_t& w0, std::uint32_t& w1) {
  w0 =
      d.child_pointer << 17 | std::uint32_t(d.far) << 16 | std::uint32_t(d.valid) << 8 | d.non_leaf;
  w1 = d.contour_pointer << 8 | d.contour_mask;
}

// The word of the first child of the descriptor at word `w` (its first word `w0`), through the
// far pointer when the far bit is set. Children are consecutive descriptors in octant order.
inline std::uint64_t first_child_word(const std::uint32_t* words, std::uint64_t w,
                                      std::uint32_t w0) {
  return w + ((w0 >> 16 & 1) ? words[w + (w0 >> 17)] : 2 * std::uint64_t(w0 >> 17));
}

// Entries of `mask` below octant c: the rank of child c among its siblings.
inline std::uint32_t rank_below(std::uint32_t mask, std::uint32_t c) {
  return std::uint32_t(std::popcount(mask & ((1u << c) - 1)));
}

// A contour: the slab { u in [0,1]^3 : lo <= n . (u - 1/2) <= hi } of the voxel's cube, u the
// position in the voxel's own coordinates, n the integer normal (components -32..31) and
//   lo = position * unit,  hi = (position + thickness) * unit,  unit = (|nx|+|ny|+|nz|) / 128,
// so the slab spans at most 127/128 of the cube's extent along n. 32 bits:
//   bits 31..25 thickness (0..127), 24..18 position (signed, -64..63), 17..12 nx, 11..6 ny,
//   5..0 nz (signed).
struct Contour {
  int normal[3];
  int position, thickness;
};

inline std::uint32_t encode_contour(const Contour& c) {
  const auto field = [](int v, int bits) { return std::uint32_t(v) & ((1u << bits) - 1); };
  return field(c.thickness, 7) << 25 | field(c.position, 7) << 18 | field(c.normal[0], 6) << 12 |
         field(c.normal[1], 6) << 6 | field(c.normal[2], 6);
}
inline Contour decode_contour(std::uint32_t w) {
  // Arithmetic shifts of the word moved so the field's top bit is bit 31 sign-extend it.
  const auto field = [w](int top, int bits) {
    return int(std::int32_t(w << (31 - top)) >> (32 - bits));
  };
  return {{field(17, 6), field(11, 6), field(5, 6)}, field(24, 7), int(w >> 25)};
}
inline int contour_extent(const Contour& c) {
  return std::abs(c.normal[0]) + std::abs(c.normal[1]) + std::abs(c.normal[2]);
}

}  // namespace kiln::format
