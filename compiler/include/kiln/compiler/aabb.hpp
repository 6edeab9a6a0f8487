#pragma once

#include <algorithm>
#include <limits>

#include "kiln/formats/geometry.hpp"

namespace kiln {

// An axis-aligned box for building; empty when lo > hi.
struct Aabb {
  float lo[3] = {std::numeric_limits<float>::infinity(), std::numeric_limits<float>::infinity(),
                 std::numeric_limits<float>::infinity()};
  float hi[3] = {-std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
                 -std::numeric_limits<float>::infinity()};

  void grow(const format::Float3& p) {
    const float v[3] = {p.x, p.y, p.z};
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], v[a]), hi[a] = std::max(hi[a], v[a]);
  }
  void grow(const Aabb& b) {
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], b.lo[a]), hi[a] = std::max(hi[a], b.hi[a]);
  }
  bool empty() const { return lo[0] > hi[0] || lo[1] > hi[1] || lo[2] > hi[2]; }
  // Half the surface area: the SAH only ever uses ratios.
  float half_area() const {
    if (empty()) return 0.0f;
    const float dx = hi[0] - lo[0], dy = hi[1] - lo[1], dz = hi[2] - lo[2];
    return dx * dy + dy * dz + dz * dx;
  }
  float centroid(int axis) const { return 0.5f * (lo[axis] + hi[axis]); }
  static Aabb intersection(const Aabb& a, const Aabb& b) {
    Aabb r;
    for (int i = 0; i < 3; ++i)
      r.lo[i] = std::max(a.lo[i], b.lo[i]), r.hi[i] = std::min(a.hi[i], b.hi[i]);
    return r;
  }
};

}  // namespace kiln
