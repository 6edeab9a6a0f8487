// Shewchuk's adaptive orient2d, written from the paper's description (section 4 and 6):
// a floating-point filter (error bound A), then the exact determinant of the rounded
// differences as a 4-component expansion (bound B), then a first-order correction by the
// differences' round-off tails (bound C), then the exact expansion (stage D). Each stage runs
// only when the previous one cannot certify the sign, so the common case costs a few flops.
#include "kiln/runtime/predicates2.hpp"

#include "predicates2_inline.hpp"

#include <algorithm>
#include <cmath>

#ifdef __FAST_MATH__
#error "predicates2.cpp needs IEEE arithmetic: do not build it with -ffast-math"
#endif

namespace kiln {

namespace {

using format::Double2;

constexpr double kEpsilon = 0x1p-53;        // half an ulp of 1: the rounding unit
constexpr double kSplitter = 0x1p27 + 1.0;  // splits a double into two 26-bit halves
constexpr double kResultErrBound = (3.0 + 8.0 * kEpsilon) * kEpsilon;
constexpr double kCcwErrBoundB = (2.0 + 12.0 * kEpsilon) * kEpsilon;
constexpr double kCcwErrBoundC = (9.0 + 64.0 * kEpsilon) * kEpsilon * kEpsilon;

// x + y = a + b exactly, |y| <= ulp(x) / 2 (Knuth's two-sum, no ordering needed).
inline void two_sum(double a, double b, double& x, double& y) {
  x = a + b;
  const double b_virtual = x - a;
  const double a_virtual = x - b_virtual;
  y = (a - a_virtual) + (b - b_virtual);
}

// y = the round-off of x = fl(a - b).
inline double two_diff_tail(double a, double b, double x) {
  const double b_virtual = a - x;
  const double a_virtual = x + b_virtual;
  return (a - a_virtual) + (b_virtual - b);
}

inline void two_diff(double a, double b, double& x, double& y) {
  x = a - b;
  y = two_diff_tail(a, b, x);
}

// a = hi + lo, each with at most 26 significant bits (Dekker's split).
inline void split(double a, double& hi, double& lo) {
  const double c = kSplitter * a;
  const double big = c - a;
  hi = c - big;
  lo = a - hi;
}

// x + y = a * b exactly (Dekker's two-product; exact because no product is fused).
inline void two_product(double a, double b, double& x, double& y) {
  x = a * b;
  double ahi, alo, bhi, blo;
  split(a, ahi, alo);
  split(b, bhi, blo);
  const double err1 = x - ahi * bhi;
  const double err2 = err1 - alo * bhi;
  const double err3 = err2 - ahi * blo;
  y = alo * blo - err3;
}

// (a1 + a0) - (b1 + b0) as a nonoverlapping expansion x[0..3], least significant first.
inline void two_two_diff(double a1, double a0, double b1, double b0, double x[4]) {
  double i, j, k;
  two_diff(a0, b0, i, x[0]);
  two_sum(a1, i, j, k);
  double m;
  two_diff(k, b1, m, x[1]);
  two_sum(j, m, x[3], x[2]);
}

// h = e + f for nonoverlapping expansions (increasing magnitude), zero components removed;
// returns h's length. h must have room for elen + flen components.
int fast_expansion_sum_zeroelim(int elen, const double* e, int flen, const double* f, double* h) {
  int ei = 0, fi = 0, hi = 0;
  double q, q_new, hh;
  // The smaller-magnitude head goes first, as in a merge of two sorted lists.
  auto take_e = [&] { return fi >= flen || (ei < elen && ((f[fi] > e[ei]) == (f[fi] > -e[ei]))); };
  q = take_e() ? e[ei++] : f[fi++];
  while (ei < elen || fi < flen) {
    // two_sum where the paper may use fast_two_sum: both give the same exact pair.
    two_sum(q, take_e() ? e[ei++] : f[fi++], q_new, hh);
    q = q_new;
    if (hh != 0.0) h[hi++] = hh;
  }
  if (q != 0.0 || hi == 0) h[hi++] = q;
  return hi;
}

double estimate(int len, const double* e) {
  double sum = e[0];
  for (int i = 1; i < len; ++i) sum += e[i];
  return sum;
}

}  // namespace

// The adaptive stages B, C and D (the paper's orient2dadapt).
double detail::orient2d_adapt(const Double2& a, const Double2& b, const Double2& c, double detsum) {
  const double acx = a.x - c.x, bcx = b.x - c.x, acy = a.y - c.y, bcy = b.y - c.y;
  double detleft, detlefttail, detright, detrighttail;
  two_product(acx, bcy, detleft, detlefttail);
  two_product(acy, bcx, detright, detrighttail);
  double B[4];
  two_two_diff(detleft, detlefttail, detright, detrighttail, B);
  double det = estimate(4, B);
  double errbound = kCcwErrBoundB * detsum;
  if (det >= errbound || -det >= errbound) return det;

  const double acxtail = two_diff_tail(a.x, c.x, acx), bcxtail = two_diff_tail(b.x, c.x, bcx);
  const double acytail = two_diff_tail(a.y, c.y, acy), bcytail = two_diff_tail(b.y, c.y, bcy);
  if (acxtail == 0.0 && acytail == 0.0 && bcxtail == 0.0 && bcytail == 0.0) return det;

  errbound = kCcwErrBoundC * detsum + kResultErrBound * std::fabs(det);
  det += (acx * bcytail + bcy * acxtail) - (acy * bcxtail + bcx * acytail);
  if (det >= errbound || -det >= errbound) return det;

  double s1, s0, t1, t0, u[4], C1[8], C2[12], D[16];
  two_product(acxtail, bcy, s1, s0);
  two_product(acytail, bcx, t1, t0);
  two_two_diff(s1, s0, t1, t0, u);
  const int c1len = fast_expansion_sum_zeroelim(4, B, 4, u, C1);
  two_product(acx, bcytail, s1, s0);
  two_product(acy, bcxtail, t1, t0);
  two_two_diff(s1, s0, t1, t0, u);
  const int c2len = fast_expansion_sum_zeroelim(c1len, C1, 4, u, C2);
  two_product(acxtail, bcytail, s1, s0);
  two_product(acytail, bcxtail, t1, t0);
  two_two_diff(s1, s0, t1, t0, u);
  const int dlen = fast_expansion_sum_zeroelim(c2len, C2, 4, u, D);
  return D[dlen - 1];
}

double orient2d(const Double2& a, const Double2& b, const Double2& c) {
  return detail::orient2d_inline(a, b, c);
}

bool crosses_ray(const Double2& a, const Double2& b, const Double2& p) {
  // Orient the edge upward so "left of the edge" means "the edge is to the right of p".
  if (a.y <= p.y && p.y < b.y) return orient2d(a, b, p) > 0.0;
  if (b.y <= p.y && p.y < a.y) return orient2d(b, a, p) > 0.0;
  return false;
}

bool shifted_segment_crosses(const Double2& c, const Double2& p, const Double2& a,
                             const Double2& b) {
  return detail::shifted_segment_crosses_inline(c, p, a, b);
}

bool segment_meets_box(const Double2& a, const Double2& b, const Double2& lo, const Double2& hi) {
  if (std::max(a.x, b.x) < lo.x || std::min(a.x, b.x) > hi.x || std::max(a.y, b.y) < lo.y ||
      std::min(a.y, b.y) > hi.y)
    return false;
  // The bounding boxes overlap, so the segment meets the box exactly when its supporting line
  // does: when the box's corners are not all strictly on one side of it.
  const double s0 = orient2d(a, b, lo), s1 = orient2d(a, b, {hi.x, lo.y});
  const double s2 = orient2d(a, b, hi), s3 = orient2d(a, b, {lo.x, hi.y});
  const bool all_left = s0 > 0 && s1 > 0 && s2 > 0 && s3 > 0;
  const bool all_right = s0 < 0 && s1 < 0 && s2 < 0 && s3 < 0;
  return !all_left && !all_right;
}

bool ring_contains(std::span<const Double2> ring, const Double2& p) {
  bool inside = false;
  for (std::size_t i = 0, n = ring.size(); i < n; ++i)
    inside ^= crosses_ray(ring[i], ring[i + 1 == n ? 0 : i + 1], p);
  return inside;
}

}  // namespace kiln
