// Setup of the closed-form column tests (voxelize_columns.hpp) and their error margins.
//
// Why the margins hold. Let u = 2^-53 (unit roundoff) and M = the largest extent of the
// triangle's bounding box plus 2 (grid units), so that for every candidate voxel with centre c:
// |corner - c| <= M per axis, |edge| <= 2M per axis, and the local centre (c minus our integer
// origin) is within M as well. The predicate (triangle_overlaps_box) computes a = fl(v - c)
// (error <= uM per component), edges e = fl(b - a) (<= 4uM), and for each axis X a slab test.
//  - Edge axes X = cross(unit, e) take two components of e exactly, so |X - X_exact| <= 4uM
//    per component and |X| <= 2M; p = a . X then differs from the exact A . X_exact by at most
//    uM*4M + M*8uM + 12uM^2 (the two products and one sum rounded) = 24uM^2, and r by 8uM:
//    the separating quantity by <= 32uM^2.
//  - The normal n = cross(e0, e1): |n - N| <= 48uM^2 per component, |N| <= 8M^2; p = a . n
//    differs by <= 3(uM*8M^2 + M*48uM^2) + 72uM^3 = 240uM^3, r by 96uM^2: <= 336uM^3.
// Our own evaluation (corners minus an integer origin, edges, axes, slab bounds, c . X) has the
// same structure and the same bounds (<= 32uM^2 + 12uM^2 and <= 336uM^3 + 144uM^3). The margins
// below, 256uM^2 and 2048uM^3, exceed the sum of both by more than 2x (the O(u^2) terms are far
// below that). Dividing by the axis' component along the level's axis turns them into a distance
// along it; the division and the multiply-adds that evaluate the bound per column add at most
// 4u(|bound| + (|qu| + |qv|)M + 1), covered by the 16u(...) term. Underflow only adds absolute
// errors far below u (M >= 2). In grid units the margin is ~1e-12 voxel for ordinary triangles;
// it grows only for slivers and degenerate triangles, whose voxels then go to the exact test.
// Edge axes have an exact zero component, so their projections are formed from the two others
// (the same value up to the sign of a zero); the divisions run two at a time on SSE2, which
// rounds as the scalar code does.
#include "voxelize_columns.hpp"

#include <cstring>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace kiln::voxelize_detail {

namespace {

constexpr double kRoundoff = 0x1p-53;

double component(const std::array<double, 3>& v, int i) {
  return v[std::size_t(i)];
}

}  // namespace

VoxelRange candidate_range(const GridTriangle& t, const VoxelRange& clip) {
  VoxelRange r;
  for (int a = 0; a < 3; ++a) {
    const double lo =
        std::min({format::at(t.v[0], a), format::at(t.v[1], a), format::at(t.v[2], a)});
    const double hi =
        std::max({format::at(t.v[0], a), format::at(t.v[1], a), format::at(t.v[2], a)});
    // A box [k, k+1] touches a coordinate in [lo, hi] for k in [ceil(lo) - 1, floor(hi)].
    r.lo[a] = std::max(clip.lo[a], ceil_to_int(lo) - 1);
    r.hi[a] = std::min(clip.hi[a], floor_to_int(hi));
  }
  return r;
}

// The corners relative to an integer origin, the candidate range and the extent M; false when
// the triangle lies outside any grid or its range is empty.
bool TriangleColumns::place(const GridTriangle& t) {
  double extent = 0;
  for (int k = 0; k < 3; ++k) {
    const double v[3] = {format::at(t.v[0], k), format::at(t.v[1], k), format::at(t.v[2], k)};
    for (const double x : v)
      if (!(std::fabs(x) <= 0x1p40)) return false;  // NaN, infinite or outside any grid
    // candidate_range's bounds (never clipped nor empty within +-2^40), and the origin.
    const double lo = std::min({v[0], v[1], v[2]}), hi = std::max({v[0], v[1], v[2]});
    range_.lo[k] = ceil_to_int(lo) - 1, range_.hi[k] = floor_to_int(hi);
    origin_[k] = floor_to_int(lo);
    for (int j = 0; j < 3; ++j) {
      p_[j][std::size_t(k)] = v[j] - double(origin_[k]);
      extent = std::max(extent, p_[j][std::size_t(k)]);
    }
  }
  extent_ = extent + 2;
  return true;
}

// The test "c . axis in [min_j p_j . axis - r, max_j p_j . axis + r]", filed at the finest level
// whose axis component is non-zero (a: per column, v: per row, u: per triangle).
template <int a>
[[gnu::always_inline]] inline void TriangleColumns::add_test(const std::array<double, 3>& axis,
                                                             double margin, PendingTests& pending) {
  double lo = INFINITY, hi = -INFINITY;
  for (int j = 0; j < 3; ++j) {
    const double p = p_[j][0] * axis[0] + p_[j][1] * axis[1] + p_[j][2] * axis[2];
    lo = std::min(lo, p), hi = std::max(hi, p);
  }
  const double r = 0.5 * (std::fabs(axis[0]) + std::fabs(axis[1]) + std::fabs(axis[2]));
  file_test<a>(axis, lo - r, hi + r, margin, pending);
}

// add_test on the edge axis cross(unit i, e) of edge j, whose component along i is exactly zero:
// each corner's projection is two products (add_test's sum less its zero term, the same value up
// to the sign of a zero). None when the edge is parallel to axis i (the exact zero axis, which
// never separates).
template <int a, int i>
[[gnu::always_inline]] inline void TriangleColumns::add_edge_test(const GridTriangle& t, int j,
                                                                  const std::array<double, 3>& e,
                                                                  double margin,
                                                                  PendingTests& pending) {
  constexpr auto p = std::size_t(i + 1) % 3, q = std::size_t(i + 2) % 3;
  // (e's components are zero when the corners' are equal, so they are compared only then.)
  if (e[p] == 0 && e[q] == 0 &&
      format::at(t.v[(j + 1) % 3], int(p)) == format::at(t.v[j], int(p)) &&
      format::at(t.v[(j + 1) % 3], int(q)) == format::at(t.v[j], int(q)))
    return;
  std::array<double, 3> axis = {0, 0, 0};
  axis[p] = -e[q], axis[q] = e[p];
  double lo = INFINITY, hi = -INFINITY;
  for (int k = 0; k < 3; ++k) {
    const double d = p_[k][p] * axis[p] + p_[k][q] * axis[q];
    lo = std::min(lo, d), hi = std::max(hi, d);
  }
  const double r = 0.5 * (std::fabs(axis[p]) + std::fabs(axis[q]));
  file_test<a>(axis, lo - r, hi + r, margin, pending);
}

template <int a>
[[gnu::always_inline]] inline void TriangleColumns::file_test(const std::array<double, 3>& axis,
                                                              double lo, double hi, double margin,
                                                              PendingTests& pending) {
  const double ka = axis[a], ku = axis[(a + 1) % 3], kv = axis[(a + 2) % 3];
  if (ka != 0)
    pending.add(lo, hi, ka, ku, kv, margin, 2);
  else if (kv != 0)
    pending.add(lo, hi, kv, ku, 0, margin, 1);
  else if (ku != 0)
    pending.add(lo, hi, ku, 0, 0, margin, 0);
  else if (0 < lo - margin || 0 > hi + margin)
    empty_ = true;  // separates every voxel
  else if (!(lo + margin <= 0 && 0 <= hi - margin))
    uncertain_all_ = true;
}

// The plane test and the nine edge tests, pending, for the dominant axis a (a template argument,
// so that where each test is filed is mostly known at compile time); true when the plane test is
// the first pending one and bounds the a index.
template <int a>
bool TriangleColumns::add_tests(const GridTriangle& t, const std::array<double, 3>* e,
                                const std::array<double, 3>& n, PendingTests& pending) {
  const double m = extent_;
  add_test<a>(n, 2048 * kRoundoff * m * m * m, pending);
  const bool plane_first = pending.count == 1 && pending.level[0] == 2;
  for (int j = 0; j < 3; ++j) {
    add_edge_test<a, 0>(t, j, e[j], 256 * kRoundoff * m * m, pending);
    add_edge_test<a, 1>(t, j, e[j], 256 * kRoundoff * m * m, pending);
    add_edge_test<a, 2>(t, j, e[j], 256 * kRoundoff * m * m, pending);
  }
  return plane_first;
}

bool TriangleColumns::setup(const GridTriangle& t) {
  t_ = t;
  windowed_ = false;
  if (!place(t)) return false;
  if (window_ != nullptr && range_.hi[0] - range_.lo[0] < kWindowsPerAxis * kWindowSide &&
      range_.hi[1] - range_.lo[1] < kWindowsPerAxis * kWindowSide &&
      range_.hi[2] - range_.lo[2] < kWindowsPerAxis * kWindowSide) {
    windowed_ = true;  // the kernel decides every test (voxelize_window.hpp)
    return true;
  }
  std::array<double, 3> e[3];
  for (int j = 0; j < 3; ++j)
    for (std::size_t k = 0; k < 3; ++k) e[j][k] = p_[(j + 1) % 3][k] - p_[j][k];
  const std::array<double, 3> n = {e[0][1] * e[1][2] - e[0][2] * e[1][1],
                                   e[0][2] * e[1][0] - e[0][0] * e[1][2],
                                   e[0][0] * e[1][1] - e[0][1] * e[1][0]};
  a_ = 0;
  for (int k = 1; k < 3; ++k)
    if (std::fabs(component(n, k)) > std::fabs(component(n, a_))) a_ = k;
  if (n[0] == 0 && n[1] == 0 && n[2] == 0)  // degenerate: walk along the longest extent
    for (int k = 0; k < 3; ++k)
      if (range_.hi[k] - range_.lo[k] > range_.hi[a_] - range_.lo[a_]) a_ = k;
  u_ = (a_ + 1) % 3, v_ = (a_ + 2) % 3;
  std::fill(std::begin(count_), std::end(count_), 0);
  sure_inset_ = 0;
  uncertain_all_ = empty_ = has_plane_ = false;
  PendingTests pending;
  const bool plane_first = a_ == 0   ? add_tests<0>(t, e, n, pending)
                           : a_ == 1 ? add_tests<1>(t, e, n, pending)
                                     : add_tests<2>(t, e, n, pending);
  commit_tests(pending, plane_first);
  small_ = true;
  for (int level = 0; level < 5; ++level) {
    small_ = small_ && count_[level] <= kSmallCount[level];
    for (int k = count_[level]; k < kSmallCount[level]; ++k)
      tests_[level][k] = {-INFINITY, INFINITY, 0, 0};  // passes every centre
  }
  return !empty_;
}

// Each pending test as an interval along its level's axis: "k x + q1 cu + q2 cv in [lo, hi]"
// divided by k, widened by its margin. One loop of fixed length over all of them (it vectorizes;
// unused entries divide by 1), then each is filed (see tests_).
// The pending tests k[i] (the level's axis component) as intervals along that axis with their
// margins m[i]: "k x + q1 cu + q2 cv in [lo, hi]" divided by k. A reciprocal instead of four
// divisions: one more rounding each, within the 16u term. Entries i and i + 1 at once on SSE2.
void TriangleColumns::divide_tests(const PendingTests& p, int i, SlabInterval* out,
                                   double* m) const {
#if defined(__SSE2__)
  const __m128d k = _mm_loadu_pd(p.k + i), inv = _mm_div_pd(_mm_set1_pd(1), k);
  const __m128d sign = _mm_set1_pd(-0.0);
  const __m128d a = _mm_mul_pd(_mm_loadu_pd(p.lo + i), inv);
  const __m128d b = _mm_mul_pd(_mm_loadu_pd(p.hi + i), inv);
  const __m128d lo = _mm_min_pd(a, b), hi = _mm_max_pd(a, b);  // a or b, by the sign of k
  const __m128d qu = _mm_xor_pd(_mm_mul_pd(_mm_loadu_pd(p.q1 + i), inv), sign);
  const __m128d qv = _mm_xor_pd(_mm_mul_pd(_mm_loadu_pd(p.q2 + i), inv), sign);
  auto abs = [&](__m128d x) { return _mm_andnot_pd(sign, x); };
  const __m128d spread =
      _mm_add_pd(_mm_add_pd(_mm_max_pd(abs(lo), abs(hi)),
                            _mm_mul_pd(_mm_add_pd(abs(qu), abs(qv)), _mm_set1_pd(extent_))),
                 _mm_set1_pd(1));
  const __m128d margin = _mm_add_pd(_mm_mul_pd(_mm_loadu_pd(p.margin + i), abs(inv)),
                                    _mm_mul_pd(_mm_set1_pd(16 * kRoundoff), spread));
  // Each SlabInterval as two 16-byte stores (its fields in order), so that the 16-byte loads
  // that copy it forward from them (four 8-byte stores would stall each load).
  const __m128d l = _mm_sub_pd(lo, margin), h = _mm_add_pd(hi, margin);
  static_assert(sizeof(SlabInterval) == 4 * sizeof(double));
  alignas(16) double pairs[8];
  _mm_store_pd(pairs, _mm_unpacklo_pd(l, h)), _mm_store_pd(pairs + 2, _mm_unpacklo_pd(qu, qv));
  _mm_store_pd(pairs + 4, _mm_unpackhi_pd(l, h)), _mm_store_pd(pairs + 6, _mm_unpackhi_pd(qu, qv));
  std::memcpy(&out[i], pairs, sizeof(SlabInterval));
  std::memcpy(&out[i + 1], pairs + 4, sizeof(SlabInterval));
  _mm_storeu_pd(m + i, margin);
#else
  for (int j = i; j < i + 2; ++j) {
    const double inv = 1 / p.k[j], a = p.lo[j] * inv, b = p.hi[j] * inv;
    const double lo = std::min(a, b), hi = std::max(a, b);  // a or b, by the sign of k
    const double qu = -(p.q1[j] * inv), qv = -(p.q2[j] * inv);
    m[j] = p.margin[j] * std::fabs(inv) + 16 * kRoundoff *
                                              (std::max(std::fabs(lo), std::fabs(hi)) +
                                               (std::fabs(qu) + std::fabs(qv)) * extent_ + 1);
    out[j] = {lo - m[j], hi + m[j], qu, qv};
  }
#endif
}

// Each pending test divided (divide_tests) and filed (file_interval).
void TriangleColumns::commit_tests(PendingTests& p, bool plane_first) {
  if (p.count % 2 != 0)  // a harmless last entry for the pairs
    p.lo[p.count] = p.hi[p.count] = p.q1[p.count] = p.q2[p.count] = p.margin[p.count] = 0,
    p.k[p.count] = 1;
  SlabInterval s[PendingTests::kMax + 1];
  double m[PendingTests::kMax + 1];
  for (int i = 0; i < p.count; i += 2) divide_tests(p, i, s, m);
  int constant[5] = {-1, -1, -1, -1, -1};
  double inset = sure_inset_;  // a local: the member would go through memory on every test
  for (int i = 0; i < p.count; ++i) {
    // NaN or infinity anywhere makes the margin non-finite (lo, hi, |qu|, |qv| <= m / (16u);
    // a NaN bound needs an infinite reciprocal, and the margin has margin * |inv|).
    if (!(std::fabs(m[i]) < INFINITY)) {
      uncertain_all_ = true;  // no usable bound: the exact test decides every voxel
      continue;
    }
    if (i == 0 && plane_first) has_plane_ = true, plane_ = s[0];
    file_interval(s[i], p.level[i], constant);
    inset = std::max(inset, 2 * m[i]);
  }
  sure_inset_ = inset;
}

// Files `s` by what it depends on (see tests_). Tests that do not depend on the column at all
// (qu = qv = 0: an edge parallel to a grid plane, common on quantized meshes) become one per
// level (constant[level]: its index): the largest lower and smallest upper bound, exactly what
// evaluating them one by one gives (adding w = +-0 changes no bound).
void TriangleColumns::file_interval(const SlabInterval& s, int level, int* constant) {
  if (level == 2) level = s.qv == 0 ? 3 : s.qu == 0 ? 4 : 2;
  SlabInterval* tests = tests_[level];
  if (s.qu == 0 && s.qv == 0) {
    if (constant[level] >= 0) {
      SlabInterval& c = tests[constant[level]];
      c.lo_m = std::max(c.lo_m, s.lo_m), c.hi_m = std::min(c.hi_m, s.hi_m);
      return;
    }
    constant[level] = count_[level];
  }
  tests[count_[level]++] = s;
}

void TriangleColumns::reach_along_a(std::int64_t u0, std::int64_t u1, std::int64_t v0,
                                    std::int64_t v1, std::int64_t& a0, std::int64_t& a1) const {
  a0 = range_.lo[a_], a1 = range_.hi[a_];
  if (!has_plane_) return;
  const SlabInterval& s = plane_;
  double lo = INFINITY, hi = -INFINITY;
  for (const std::int64_t iu : {u0, u1})
    for (const std::int64_t iv : {v0, v1}) {
      const double w =
          s.qu * (double(iu - origin_[u_]) + 0.5) + s.qv * (double(iv - origin_[v_]) + 0.5);
      lo = std::min(lo, s.lo_m + w), hi = std::max(hi, s.hi_m + w);
    }
  std::int64_t l, h;
  centre_range(lo, hi, range_.lo[a_] - origin_[a_], range_.hi[a_] - origin_[a_], l, h);
  // One voxel of slack: the columns' own evaluation rounds differently from the corners'.
  a0 = std::max(range_.lo[a_], l + origin_[a_] - 1);
  a1 = std::min(range_.hi[a_], h + origin_[a_] + 1);
}

}  // namespace kiln::voxelize_detail
