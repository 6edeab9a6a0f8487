// The exact extent of a triangle inside an axis-aligned box (perfect splits need it, not the
// overlap of the triangle's box with the cell).
#pragma once

#include "kiln/formats/geometry.hpp"

namespace kiln {

/// Bounds of the part of triangle (a, b, c) inside `cell`, rounded outwards to float and clamped
/// to the cell; empty when the triangle misses the cell. Sutherland-Hodgman in double.
format::Box3f clip_triangle_to_box(const format::Float3& a, const format::Float3& b,
                                   const format::Float3& c, const format::Box3f& cell);

}  // namespace kiln
