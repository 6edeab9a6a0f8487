// On-disk layout of the SAH k-d tree: a depth-first array of 8-byte nodes (pbrt-v3 style), the
// primitive ids of the leaves in leaf order, and one copy of every triangle's corners by
// primitive id (what the watertight test reads, without an index indirection).
#pragma once

#include <bit>
#include <cstdint>

#include "kiln/formats/container.hpp"
#include "kiln/formats/ray_triangle.hpp"

namespace kiln::format {

inline constexpr std::uint32_t kSectionKdNodes = fourcc('K', 'D', 'T', 'N');
inline constexpr std::uint32_t kSectionKdPrimIds = fourcc('K', 'D', 'T', 'P');
inline constexpr std::uint32_t kSectionKdTriangles = fourcc('K', 'D', 'T', 'T');

// Interior: `payload` holds the split position (float bits), `bits` = above-child index << 2 |
// axis; the below child is the next node. Leaf: `payload` = first reference, `bits` = reference
// count << 2 | 3.
struct KdNode {
  std::uint32_t payload;
  std::uint32_t bits;

  bool is_leaf() const { return (bits & 3u) == 3u; }
  std::uint32_t axis() const { return bits & 3u; }
  float split() const { return std::bit_cast<float>(payload); }
  std::uint32_t above_child() const { return bits >> 2; }
  std::uint32_t first_reference() const { return payload; }
  std::uint32_t reference_count() const { return bits >> 2; }

  static KdNode interior(int axis, float split, std::uint32_t above) {
    return {std::bit_cast<std::uint32_t>(split), above << 2 | std::uint32_t(axis)};
  }
  static KdNode leaf(std::uint32_t first, std::uint32_t count) { return {first, count << 2 | 3u}; }
};
static_assert(sizeof(KdNode) == 8);

// Node indices and reference counts live in 30 bits.
inline constexpr std::uint32_t kKdMaxIndex = (1u << 30) - 1;
// Traversal keeps a fixed stack; builders cap the depth below this.
inline constexpr std::uint32_t kKdMaxDepth = 64;

}  // namespace kiln::format
