// On-disk layout of the BVH family (bvh, sbvh): a depth-first array of 32-byte nodes, the leaf
// triangles in leaf order, and the original primitive id of each leaf reference.
#pragma once

#include <cstddef>
#include <cstdint>

#include "kiln/formats/container.hpp"
#include "kiln/formats/geometry.hpp"
#include "kiln/formats/ray_triangle.hpp"

namespace kiln::format {

inline constexpr std::uint32_t kSectionBvhNodes = fourcc('B', 'V', 'H', 'N');
inline constexpr std::uint32_t kSectionBvhTriangles = fourcc('B', 'V', 'H', 'T');
inline constexpr std::uint32_t kSectionBvhPrimIds = fourcc('B', 'V', 'H', 'P');

// pbrt-style BVH2 node. Nodes are stored in depth-first pre-order: an interior node's first
// child is the next node (i + 1), its second child is at `offset`. A leaf's references are
// [offset, offset + count) in the triangle and primitive-id sections.
struct BvhNode {
  float min[3];
  std::uint32_t offset;  // interior: index of the second child; leaf: first reference
  float max[3];
  std::uint16_t count;  // 0 for an interior node, else the leaf's reference count
  std::uint8_t axis;    // interior: the split axis (for direction-sign ordering); leaf: 0
  std::uint8_t reserved;
};
static_assert(sizeof(BvhNode) == 32);
static_assert(offsetof(BvhNode, offset) == 12);
static_assert(offsetof(BvhNode, max) == 16);
static_assert(offsetof(BvhNode, count) == 28);
static_assert(offsetof(BvhNode, axis) == 30);

// Traversal keeps a fixed stack; builders never produce a deeper tree.
inline constexpr std::uint32_t kBvhMaxDepth = 64;
inline constexpr std::uint32_t kBvhMaxLeafSize = 0xFFFF;

}  // namespace kiln::format
