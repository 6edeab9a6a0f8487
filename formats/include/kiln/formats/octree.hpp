// On-disk layout of the octree over triangles: cells split at their centre into eight until a
// leaf is small enough. One array of 8-byte nodes in breadth-first order (the children of a node
// contiguous in octant order, as the voxel DAG keeps them), the triangle ids of the leaves in
// node order, and one copy of every triangle's corners by primitive id (what the watertight
// test reads).
#pragma once

#include <cstdint>

#include "kiln/formats/container.hpp"
#include "kiln/formats/geometry.hpp"
#include "kiln/formats/ray_triangle.hpp"

namespace kiln::format {

inline constexpr std::uint32_t kSectionOctreeNodes = fourcc('O', 'C', 'T', 'N');
inline constexpr std::uint32_t kSectionOctreePrimIds = fourcc('O', 'C', 'T', 'P');
inline constexpr std::uint32_t kSectionOctreeTriangles = fourcc('O', 'C', 'T', 'T');

// Bit c of a child mask is octant c = x | y << 1 | z << 2: the child's upper half on each set
// axis. Interior (mask != 0): `first` = index of the child of the lowest set octant; the present
// children follow it in octant order, one node each; an absent octant is empty space. Leaf
// (mask == 0): `first` = its first reference, bits >> 8 = its reference count.
struct OctreeNode {
  std::uint32_t first;
  std::uint32_t bits;

  std::uint32_t child_mask() const { return bits & 0xFFu; }
  bool is_leaf() const { return child_mask() == 0; }
  std::uint32_t first_child() const { return first; }
  std::uint32_t first_reference() const { return first; }
  std::uint32_t reference_count() const { return bits >> 8; }

  static OctreeNode interior(std::uint32_t mask, std::uint32_t first_child) {
    return {first_child, mask & 0xFFu};
  }
  static OctreeNode leaf(std::uint32_t first, std::uint32_t count) { return {first, count << 8}; }
};
static_assert(sizeof(OctreeNode) == 8);

// A leaf's reference count lives in 24 bits.
inline constexpr std::uint32_t kOctreeMaxLeafReferences = (1u << 24) - 1;
// Levels below the root (root = depth 0): traversal stacks are sized by it, views refuse deeper.
inline constexpr std::uint32_t kOctreeMaxDepth = 24;

// The centre of [lo, hi] on one axis: the one formula the builder and every walk use, so a
// child's cell is the same float box on both sides and sibling cells share their faces exactly.
inline float octree_mid(float lo, float hi) {
  return 0.5f * (lo + hi);
}

// The cell of octant `octant` of `cell`.
inline Box3f octree_child_cell(const Box3f& cell, std::uint32_t octant) {
  Box3f child = cell;
  for (int a = 0; a < 3; ++a) {
    const float mid = octree_mid(at(cell.min, a), at(cell.max, a));
    if (octant >> a & 1u)
      at(child.min, a) = mid;
    else
      at(child.max, a) = mid;
  }
  return child;
}

}  // namespace kiln::format
