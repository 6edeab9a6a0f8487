// The hot paths of the exact 2D predicates, inline for the runtime's own query loops: orient2d's
// floating-point filter (the adaptive stages stay out of line) and the shifted-segment crossing
// test. Private to the runtime: its sources are compiled with -ffp-contract=off, which the
// filter's error bound needs (a fused multiply-add would change the rounding it bounds).
#pragma once

#include <algorithm>
#include <cmath>

#include "kiln/formats/vector.hpp"

namespace kiln::detail {

/// Shewchuk's stages B-D (predicates2.cpp), for inputs the filter could not decide.
double orient2d_adapt(const format::Double2& a, const format::Double2& b, const format::Double2& c,
                      double detsum);

inline constexpr double kCcwErrBoundA = (3.0 + 16.0 * 0x1p-53) * 0x1p-53;

inline double orient2d_inline(const format::Double2& a, const format::Double2& b,
                              const format::Double2& c) {
  const double detleft = (a.x - c.x) * (b.y - c.y);
  const double detright = (a.y - c.y) * (b.x - c.x);
  const double det = detleft - detright;
  double detsum;
  if (detleft > 0.0) {
    if (detright <= 0.0) return det;  // the two terms have opposite signs: no cancellation
    detsum = detleft + detright;
  } else if (detleft < 0.0) {
    if (detright >= 0.0) return det;
    detsum = -detleft - detright;
  } else {
    return det;  // detleft == 0 exactly: det = -detright, whose rounding keeps its sign
  }
  const double errbound = kCcwErrBoundA * detsum;
  if (det >= errbound || -det >= errbound) return det;
  if (!std::isfinite(detsum)) return det;  // no exact answer for overflowing inputs
  return orient2d_adapt(a, b, c, detsum);
}

// Sign of orient2d(c + s, p + s, v), s = (eps, delta): orient(c, p, v) + d.y eps - d.x delta,
// d = p - c, so the shift decides only when v is on the line: by d.y, else by -d.x.
inline int side_of_shifted_line(const format::Double2& c, const format::Double2& p,
                                const format::Double2& v) {
  const double o = orient2d_inline(c, p, v);
  if (o != 0) return o > 0 ? 1 : -1;
  if (p.y != c.y) return p.y > c.y ? 1 : -1;
  return p.x > c.x ? -1 : p.x < c.x ? 1 : 0;
}

// Sign of orient2d(a, b, q + s): orient(a, b, q) + (b.x - a.x) delta - (b.y - a.y) eps.
inline int side_of_shifted_point(const format::Double2& a, const format::Double2& b,
                                 const format::Double2& q) {
  const double o = orient2d_inline(a, b, q);
  if (o != 0) return o > 0 ? 1 : -1;
  if (b.y != a.y) return b.y > a.y ? -1 : 1;
  return b.x > a.x ? 1 : b.x < a.x ? -1 : 0;
}

// shifted_segment_crosses_inline for an edge whose box meets the segment's closed box.
inline bool shifted_segment_crosses_unboxed(const format::Double2& c, const format::Double2& p,
                                            const format::Double2& a, const format::Double2& b) {
  const int sa = side_of_shifted_line(c, p, a), sb = side_of_shifted_line(c, p, b);
  if (sa == 0 || sa == sb) return false;
  const int sc = side_of_shifted_point(a, b, c), sp = side_of_shifted_point(a, b, p);
  return sc != 0 && sc != sp;
}

inline bool shifted_segment_crosses_inline(const format::Double2& c, const format::Double2& p,
                                           const format::Double2& a, const format::Double2& b) {
  // Boxes first: the shifted segment reaches past its box by infinitesimals only on the max
  // sides, so closed comparisons reject only edges it cannot meet.
  // Bitwise ors: one branch instead of four, most edges of a cell being rejected here.
  if ((std::max(a.x, b.x) < std::min(c.x, p.x)) | (std::min(a.x, b.x) > std::max(c.x, p.x)) |
      (std::max(a.y, b.y) < std::min(c.y, p.y)) | (std::min(a.y, b.y) > std::max(c.y, p.y)))
    return false;
  return shifted_segment_crosses_unboxed(c, p, a, b);
}

}  // namespace kiln::detail
