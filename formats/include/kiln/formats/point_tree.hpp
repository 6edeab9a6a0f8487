// On-disk layout of the point k-d tree: a depth-first array of 12-byte nodes, the points in leaf
// order (so a leaf's points are contiguous in memory) and, beside them, each point's vertex index.
#pragma once

#include <bit>
#include <cstdint>

#include "kiln/formats/container.hpp"

namespace kiln::format {

inline constexpr std::uint32_t kSectionPointNodes = fourcc('P', 'K', 'D', 'N');
inline constexpr std::uint32_t kSectionPointPositions = fourcc('P', 'K', 'D', 'V');
inline constexpr std::uint32_t kSectionPointIds = fourcc('P', 'K', 'D', 'I');

// Interior: the below child is the next node; `bits` = above-child index << 2 | axis; `low` and
// `high` (float bits) are the largest coordinate on the axis among the below child's points and
// the smallest among the above child's. Searches measure distance to that empty gap rather than
// to one plane, which prunes more (nanoflann's divlow/divhigh).
// Leaf: `low` = first point, `high` = point count, `bits` = 3.
struct PointNode {
  std::uint32_t low;
  std::uint32_t high;
  std::uint32_t bits;

  bool is_leaf() const { return (bits & 3u) == 3u; }
  std::uint32_t axis() const { return bits & 3u; }
  std::uint32_t above_child() const { return bits >> 2; }
  float below_max() const { return std::bit_cast<float>(low); }
  float above_min() const { return std::bit_cast<float>(high); }
  std::uint32_t first_point() const { return low; }
  std::uint32_t point_count() const { return high; }

  static PointNode interior(int axis, float below_max, float above_min, std::uint32_t above) {
    return {std::bit_cast<std::uint32_t>(below_max), std::bit_cast<std::uint32_t>(above_min),
            above << 2 | std::uint32_t(axis)};
  }
  static PointNode leaf(std::uint32_t first, std::uint32_t count) { return {first, count, 3u}; }
};
static_assert(sizeof(PointNode) == 12);

// Node indices live in 30 bits.
inline constexpr std::uint32_t kPointMaxIndex = (1u << 30) - 1;
// Searches recurse once per level; builders stay below this depth.
inline constexpr std::uint32_t kPointMaxDepth = 64;

}  // namespace kiln::format
