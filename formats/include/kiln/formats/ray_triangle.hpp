// A triangle copied beside a ray structure's nodes, in the order its leaves reference it, so a
// leaf's triangles are contiguous: the three corners are exactly what the watertight ray-triangle
// test (Woop et al. 2013) consumes.
#pragma once

#include "kiln/formats/geometry.hpp"

namespace kiln::format {

struct RayTriangle {
  Float3 v0, v1, v2;
};
static_assert(sizeof(RayTriangle) == 36);

}  // namespace kiln::format
