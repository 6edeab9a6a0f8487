// Element layouts of the geometry sections.
#pragma once

#include <cstddef>
#include <cstdint>

namespace kiln::format {

struct Float3 {
  float x, y, z;
};
static_assert(sizeof(Float3) == 12);
static_assert(offsetof(Float3, z) == 8);

// Vertex indices of one triangle, counter-clockwise as imported.
struct Triangle {
  std::uint32_t v[3];
};
static_assert(sizeof(Triangle) == 12);

}  // namespace kiln::format
