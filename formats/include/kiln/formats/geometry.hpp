// Element layouts of the input sections, and the float box the manifest's bounds use.
#pragma once

#include <cstddef>
#include <cstdint>

namespace kiln::format {

struct Float3 {
  float x, y, z;
};
static_assert(sizeof(Float3) == 12);
static_assert(offsetof(Float3, z) == 8);

// An axis-aligned box; all zero for an empty input.
struct Box3f {
  Float3 min, max;
};
static_assert(sizeof(Box3f) == 24);

// Vertex indices of one triangle, counter-clockwise as imported.
struct Triangle {
  std::uint32_t v[3];
};
static_assert(sizeof(Triangle) == 12);

}  // namespace kiln::format
