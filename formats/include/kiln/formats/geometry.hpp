// Element layouts of the input sections (positions are Float3, from the vector family).
#pragma once

#include <cstdint>

#include "kiln/formats/vector.hpp"

namespace kiln::format {

// Vertex indices of one triangle, counter-clockwise as imported.
struct Triangle {
  std::uint32_t v[3];
};
static_assert(sizeof(Triangle) == 12);

}  // namespace kiln::format
