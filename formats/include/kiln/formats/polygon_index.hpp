// On-disk layout of the polygon index (point in polygon over a polygon layer): a region
// quadtree over the layer's bounds, stored as a depth-first array of sibling groups, whose leaf
// cells list, per polygon that may contain a point of the cell, either "wholly inside" or the
// edges whose crossings decide it (docs/FORMAT.md, "Polygon index").
#pragma once

#include <cstdint>

#include "kiln/formats/container.hpp"
#include "kiln/formats/vector.hpp"

namespace kiln::format {

inline constexpr std::uint32_t kSectionPolygonIndexNodes = fourcc('P', 'I', 'N', 'D');
inline constexpr std::uint32_t kSectionPolygonIndexEntries = fourcc('P', 'I', 'E', 'N');
inline constexpr std::uint32_t kSectionPolygonIndexEdges = fourcc('P', 'I', 'E', 'D');

/// A quadtree node. Interior (`count` == kPolygonNodeInterior): `first` is the index of its
/// four children, stored together (child = (x >= mid.x) | (y >= mid.y) << 1), always after the
/// node itself. Leaf: entries `first .. first + count` of the entry array.
struct PolygonIndexNode {
  std::uint32_t first;
  std::uint32_t count;

  bool is_leaf() const;
};
inline constexpr std::uint32_t kPolygonNodeInterior = 0xFFFFFFFFu;
inline bool PolygonIndexNode::is_leaf() const {
  return count != kPolygonNodeInterior;
}
static_assert(sizeof(PolygonIndexNode) == 8);

/// One polygon of a leaf. `edge_count` == kPolygonWhollyInside: the cell's closed area lies in
/// the polygon (no edge of it meets the cell). Else bit 31 of `edge_count`
/// (kPolygonCentreInside) says whether the cell's centre is in the polygon, and its low 31 bits
/// count the polygon's edges that meet the closed cell, `first_edge ..`: a point p of the cell is
/// in the polygon when the centre is, flipped once per edge that the segment from the centre to
/// p crosses (both ends shifted by the boundary rule's infinitesimal, docs/FORMAT.md). Entries
/// of a leaf are sorted by polygon index (hence by feature index).
struct PolygonIndexEntry {
  std::uint32_t polygon;
  std::uint32_t first_edge;
  std::uint32_t edge_count;

  bool wholly_inside() const;
  bool centre_inside() const;
  std::uint32_t edges() const;
};
inline constexpr std::uint32_t kPolygonWhollyInside = 0xFFFFFFFFu;
inline constexpr std::uint32_t kPolygonCentreInside = 0x80000000u;
inline bool PolygonIndexEntry::wholly_inside() const {
  return edge_count == kPolygonWhollyInside;
}
inline bool PolygonIndexEntry::centre_inside() const {
  return (edge_count & kPolygonCentreInside) != 0;
}
inline std::uint32_t PolygonIndexEntry::edges() const {
  return wholly_inside() ? 0 : edge_count & ~kPolygonCentreInside;
}
static_assert(sizeof(PolygonIndexEntry) == 12);

/// A cell's centre, as builder and view compute it.
constexpr Double2 quadtree_centre(const Box2d& box) {
  return {0.5 * box.min.x + 0.5 * box.max.x, 0.5 * box.min.y + 0.5 * box.max.y};
}

/// An edge: indices of its two vertices in the layer's vertex array (a ring's closing edge runs
/// from its last vertex to its first).
struct PolygonIndexEdge {
  std::uint32_t a;
  std::uint32_t b;
};
static_assert(sizeof(PolygonIndexEdge) == 8);

/// Deeper trees are refused at open: queries descend at most this many levels.
inline constexpr std::uint32_t kPolygonIndexMaxDepth = 30;

/// The quadrant of `box` that child `child` covers: builder and view compute it alike.
constexpr Box2d quadtree_child_box(const Box2d& box, std::uint32_t child) {
  const Double2 mid{0.5 * box.min.x + 0.5 * box.max.x, 0.5 * box.min.y + 0.5 * box.max.y};
  Box2d c = box;
  (child & 1u ? c.min.x : c.max.x) = mid.x;
  (child & 2u ? c.min.y : c.max.y) = mid.y;
  return c;
}

/// Which child of `box` holds `p` (a point on a split line goes to the upper or right side).
constexpr std::uint32_t quadtree_child_of(const Box2d& box, const Double2& p) {
  const Double2 mid{0.5 * box.min.x + 0.5 * box.max.x, 0.5 * box.min.y + 0.5 * box.max.y};
  return std::uint32_t(p.x >= mid.x) | std::uint32_t(p.y >= mid.y) << 1;
}

}  // namespace kiln::format
