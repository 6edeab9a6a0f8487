// On-disk layout of the bucket PR quadtree over a 2D point table: a depth-first array of 12-byte
// nodes, the points in leaf order as Double2 copies (a leaf's bucket, and every subtree's points,
// contiguous) and, beside them, each point's index in the table's points.
//
// Cells are implicit: the root cell is the square stored in the description, and a node's cell
// is its parent's quarter named by its quadrant, cut at quad_middle(). Builder, view and verify
// all cut with that one function, so a point's quadrant and its cell agree bit for bit.
#pragma once

#include <cstdint>

#include "kiln/formats/container.hpp"
#include "kiln/formats/vector.hpp"

namespace kiln::format {

inline constexpr std::uint32_t kSectionQuadNodes = fourcc('Q', 'T', 'N', 'D');
inline constexpr std::uint32_t kSectionQuadPoints = fourcc('Q', 'T', 'P', 'T');  // Double2
inline constexpr std::uint32_t kSectionQuadIds = fourcc('Q', 'T', 'I', 'D');     // uint32

// Every node, leaf or not, holds the range of points of its subtree (`first`, `count`), so a
// range query reports a subtree whose cell lies inside the box without testing its points.
// `bits` = end << 3 | leaf << 2 | quadrant: `end` is one past the subtree's last node (a leaf's
// is its own index + 1); an interior node's children are the nodes from its index + 1 up to
// `end`, each found at the `end` of the one before, in ascending quadrant order, empty quadrants
// left out. Quadrant bit 0 = the upper half in x, bit 1 = the upper half in y.
struct QuadNode {
  std::uint32_t first;
  std::uint32_t count;
  std::uint32_t bits;

  bool is_leaf() const { return (bits & 4u) != 0; }
  std::uint32_t quadrant() const { return bits & 3u; }
  std::uint32_t end() const { return bits >> 3; }

  static QuadNode make(std::uint32_t first, std::uint32_t count, std::uint32_t end, bool leaf,
                       std::uint32_t quadrant) {
    return {first, count, end << 3 | (leaf ? 4u : 0u) | quadrant};
  }
};
static_assert(sizeof(QuadNode) == 12);

// Node indices (and so `end`) live in 29 bits.
inline constexpr std::uint32_t kQuadMaxNodes = (1u << 29) - 1;
// The deepest a leaf may be (root = level 0): bounds every query's stack. The builder's
// max-depth option stays at or below it.
inline constexpr std::uint32_t kQuadMaxDepth = 48;

// Where a cell [lo, hi] is cut on one axis. Halves taken separately so huge coordinates cannot
// overflow; a point goes to the upper half when its coordinate is >= the middle.
constexpr double quad_middle(double lo, double hi) {
  return 0.5 * lo + 0.5 * hi;
}

// The cell of quadrant `q` of `cell` (closed: the halves share the middle line).
constexpr Box2d quad_child_cell(const Box2d& cell, std::uint32_t q) {
  const double mx = quad_middle(cell.min.x, cell.max.x), my = quad_middle(cell.min.y, cell.max.y);
  Box2d c = cell;
  ((q & 1u) ? c.min.x : c.max.x) = mx;
  ((q & 2u) ? c.min.y : c.max.y) = my;
  return c;
}

// The quadrant of `cell` that holds `p`.
constexpr std::uint32_t quad_quadrant(const Box2d& cell, const Double2& p) {
  return (p.x >= quad_middle(cell.min.x, cell.max.x) ? 1u : 0u) |
         (p.y >= quad_middle(cell.min.y, cell.max.y) ? 2u : 0u);
}

// The squared distance every 2D query and its brute-force reference use: dx * dx + dy * dy.
constexpr double distance_squared(const Double2& a, const Double2& b) {
  const double dx = a.x - b.x, dy = a.y - b.y;
  return dx * dx + dy * dy;
}

}  // namespace kiln::format
