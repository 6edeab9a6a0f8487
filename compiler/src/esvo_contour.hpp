// Contours for the ESVO builder (Laine & Karras 2010, §5): fitting one to the triangles inside a
// voxel, and deciding whether a contoured voxel approximates the surface well enough to stop.
// Everything is in grid units (a finest voxel is a unit cube).
#pragma once

#include <cstdint>
#include <optional>
#include <span>

#include "kiln/formats/esvo.hpp"
#include "polygon_clip.hpp"

namespace kiln::esvo {

// The slab lo <= n . p <= hi.
struct Slab {
  double n[3];
  double lo, hi;
};

// A voxel's cube: [corner, corner + side] on each axis.
struct Cube {
  std::uint32_t corner[3];
  std::uint32_t side;
};

// The slab a stored contour stands for, in grid units (decoded exactly as the runtime does).
Slab slab_of(const format::Contour& contour, const Cube& cube);

struct FittedContour {
  std::uint32_t word;
  Slab slab;
};

// The contour of the surface pieces `polygons` (the voxel's triangles clipped to its cube), or
// none when no candidate cuts at least 1/16 of the cube away. Candidates are the area-weighted
// mean normal and the normals of the largest pieces; each is quantised first, then its slab is
// the tightest quantised interval holding every vertex (so it contains all the geometry), and
// the one keeping the fewest of the cube's 8^3 sub-cells inside `parent` wins, as the paper
// keeps the candidate that over-estimates least within the parent's contours.
std::optional<FittedContour> fit_contour(std::span<const ClipPolygon> polygons, const Cube& cube,
                                         const Slab* parent);

// Whether every finest cell of the cube meeting `slab` (and `parent`, when given) has a surface
// cell within `reach` cells along the slab's dominant axis. `surface` holds the cube's surface
// cells as Morton codes relative to the cube's corner. Cubes wider than kMaxCoveredSide never
// qualify.
inline constexpr std::uint32_t kMaxCoveredSide = 64;
bool slab_covered(const Slab& slab, const Slab* parent, const Cube& cube,
                  std::span<const std::uint64_t> surface, std::uint64_t code_base,
                  std::uint32_t reach);

}  // namespace kiln::esvo
