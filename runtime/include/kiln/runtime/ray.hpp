// Rays and hits, laid out exactly as the RAYS and HITS files (docs/FORMAT.md).
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>

#include "kiln/formats/geometry.hpp"

namespace kiln {

struct Ray {
  format::Float3 org;
  float tmin;
  format::Float3 dir;
  float tmax;
};
static_assert(sizeof(Ray) == 32);

inline constexpr std::uint32_t kNoHit = 0xFFFFFFFFu;

// Rays per task of the batch trace_rays functions.
inline constexpr std::size_t kRaysPerTask = 4096;

struct Hit {
  float t = std::numeric_limits<float>::infinity();
  std::uint32_t prim = kNoHit;  // original primitive (triangle) id
  float u = 0, v = 0;           // barycentric weights of the triangle's second and third corners
};
static_assert(sizeof(Hit) == 16);

}  // namespace kiln
