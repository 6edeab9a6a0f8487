// The colour packing the importers share (scene.hpp's RGBA8, r in the low byte).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace kiln {

// Each channel clamped to [0, 1], then lround(x * 255). Callers reject non-finite channels first.
inline std::uint32_t pack_rgba8(double r, double g, double b, double a) {
  auto q = [](double x) { return std::uint32_t(std::lround(std::clamp(x, 0.0, 1.0) * 255.0)); };
  return q(r) | q(g) << 8 | q(b) << 16 | q(a) << 24;
}

}  // namespace kiln
