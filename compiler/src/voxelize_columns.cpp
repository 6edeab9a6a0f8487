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

namespace {

// Two doubles, one per triangle of a PreparedPair: an SSE2 register, or a plain pair without
// SSE2. min_of and max_of are std::min and std::max lane by lane ((b < a) ? b : a and
// (a < b) ? b : a, signed zeros and NaN included), so each lane computes what the scalar code did.
#if defined(__SSE2__)
struct D2 {
  __m128d x;
};
inline D2 splat(double a) {
  return {_mm_set1_pd(a)};
}
inline D2 lanes(double l0, double l1) {
  return {_mm_set_pd(l1, l0)};
}
inline D2 operator+(D2 a, D2 b) {
  return {_mm_add_pd(a.x, b.x)};
}
inline D2 operator-(D2 a, D2 b) {
  return {_mm_sub_pd(a.x, b.x)};
}
inline D2 operator*(D2 a, D2 b) {
  return {_mm_mul_pd(a.x, b.x)};
}
inline D2 operator-(D2 a) {
  return {_mm_xor_pd(a.x, _mm_set1_pd(-0.0))};
}
inline D2 abs(D2 a) {
  return {_mm_andnot_pd(_mm_set1_pd(-0.0), a.x)};
}
inline D2 min_of(D2 a, D2 b) {
  return {_mm_min_pd(b.x, a.x)};
}
inline D2 max_of(D2 a, D2 b) {
  return {_mm_max_pd(b.x, a.x)};
}
inline int lanes_within(D2 a, double bound) {  // bit l: |lane l| <= bound
  return _mm_movemask_pd(_mm_cmple_pd(abs(a).x, _mm_set1_pd(bound)));
}
// floor and ceil of lanes within +-2^40, exactly: adding 1.5 * 2^52 rounds to an integer.
inline D2 nearest(D2 a) {
  const __m128d m = _mm_set1_pd(0x1.8p52);
  return {_mm_sub_pd(_mm_add_pd(a.x, m), m)};
}
inline D2 floor_of(D2 a) {
  const __m128d t = nearest(a).x;
  return {_mm_sub_pd(t, _mm_and_pd(_mm_cmpgt_pd(t, a.x), _mm_set1_pd(1)))};
}
inline D2 ceil_of(D2 a) {
  const __m128d t = nearest(a).x;
  return {_mm_add_pd(t, _mm_and_pd(_mm_cmplt_pd(t, a.x), _mm_set1_pd(1)))};
}
inline void store(D2 a, double* out) {
  _mm_storeu_pd(out, a.x);
}
#else
struct D2 {
  double x[2];
};
template <class F>
inline D2 map(D2 a, D2 b, F f) {
  return {{f(a.x[0], b.x[0]), f(a.x[1], b.x[1])}};
}
inline D2 splat(double a) {
  return {{a, a}};
}
inline D2 lanes(double l0, double l1) {
  return {{l0, l1}};
}
inline D2 operator+(D2 a, D2 b) {
  return map(a, b, [](double x, double y) { return x + y; });
}
inline D2 operator-(D2 a, D2 b) {
  return map(a, b, [](double x, double y) { return x - y; });
}
inline D2 operator*(D2 a, D2 b) {
  return map(a, b, [](double x, double y) { return x * y; });
}
inline D2 operator-(D2 a) {
  return {{-a.x[0], -a.x[1]}};
}
inline D2 abs(D2 a) {
  return {{std::fabs(a.x[0]), std::fabs(a.x[1])}};
}
inline D2 min_of(D2 a, D2 b) {
  return map(a, b, [](double x, double y) { return std::min(x, y); });
}
inline D2 max_of(D2 a, D2 b) {
  return map(a, b, [](double x, double y) { return std::max(x, y); });
}
inline int lanes_within(D2 a, double bound) {
  return int(std::fabs(a.x[0]) <= bound) | int(std::fabs(a.x[1]) <= bound) << 1;
}
inline D2 floor_of(D2 a) {
  return {{std::floor(a.x[0]), std::floor(a.x[1])}};
}
inline D2 ceil_of(D2 a) {
  return {{std::ceil(a.x[0]), std::ceil(a.x[1])}};
}
inline void store(D2 a, double* out) {
  out[0] = a.x[0], out[1] = a.x[1];
}
#endif

// The slab bounds of `axis` (add_test's: min_j p_j . axis - r, max_j p_j . axis + r) over the
// components `ks` of the axis (an edge axis: its two non-zero ones).
template <int count>
[[gnu::always_inline]] inline void slab(const D2 (*p)[3], const D2* axis, const int* ks, double* lo,
                                        double* hi) {
  D2 l = splat(INFINITY), h = splat(-INFINITY), r = abs(axis[ks[0]]);
  for (int j = 0; j < 3; ++j) {
    D2 d = p[j][ks[0]] * axis[ks[0]];
    for (int c = 1; c < count; ++c) d = d + p[j][ks[c]] * axis[ks[c]];
    l = min_of(l, d), h = max_of(h, d);
  }
  for (int c = 1; c < count; ++c) r = r + abs(axis[ks[c]]);
  r = splat(0.5) * r;
  store(l - r, lo), store(h + r, hi);
}

}  // namespace

// Per axis: the corners' min and max (candidate_range's bounds, never clipped nor empty within
// +-2^40), the origin (floor of the min), the corners minus the origin and the extent M; then the
// edges, the normal and the ten slab tests' bounds (setup's arithmetic, two triangles at a time).
void TriangleColumns::prepare(const GridTriangle& t0, const GridTriangle& t1, PreparedPair& out) {
  D2 p[3][3], extent = splat(0);
  int inside = 3;
  for (int k = 0; k < 3; ++k) {
    D2 v[3];
    for (int j = 0; j < 3; ++j) {
      v[j] = lanes(format::at(t0.v[j], k), format::at(t1.v[j], k));
      inside &= lanes_within(v[j], 0x1p40);
    }
    const D2 lo = min_of(min_of(v[0], v[1]), v[2]), hi = max_of(max_of(v[0], v[1]), v[2]);
    const D2 origin = floor_of(lo);
    store(origin, out.floor_lo[k]), store(ceil_of(lo), out.ceil_lo[k]);
    store(floor_of(hi), out.floor_hi[k]);
    for (int j = 0; j < 3; ++j) {
      p[j][k] = v[j] - origin;
      extent = max_of(extent, p[j][k]);
      store(p[j][k], out.p[j][k]);
    }
  }
  store(extent + splat(2), out.extent);
  out.inside = inside;
  D2 e[3][3];
  for (int j = 0; j < 3; ++j)
    for (int k = 0; k < 3; ++k) e[j][k] = p[(j + 1) % 3][k] - p[j][k], store(e[j][k], out.e[j][k]);
  const D2 n[3] = {e[0][1] * e[1][2] - e[0][2] * e[1][1], e[0][2] * e[1][0] - e[0][0] * e[1][2],
                   e[0][0] * e[1][1] - e[0][1] * e[1][0]};
  for (int k = 0; k < 3; ++k) store(n[k], out.n[k]);
  constexpr int all[3] = {0, 1, 2};
  slab<3>(p, n, all, out.lo[0], out.hi[0]);
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) {
      const int ks[2] = {(i + 1) % 3, (i + 2) % 3};
      D2 axis[3] = {splat(0), splat(0), splat(0)};
      axis[ks[0]] = -e[j][ks[1]], axis[ks[1]] = e[j][ks[0]];
      slab<2>(p, axis, ks, out.lo[1 + 3 * j + i], out.hi[1 + 3 * j + i]);
    }
}

// The edge test cross(unit i, e) of edge j, whose component along i is exactly zero, filed from
// its prepared bounds. None when the edge is parallel to axis i (the exact zero axis, which
// never separates).
template <int a, int i>
[[gnu::always_inline]] inline void TriangleColumns::add_edge_test(const GridTriangle& t,
                                                                  const PreparedPair& g, int l,
                                                                  int j, double margin,
                                                                  PendingTests& pending) {
  constexpr int p = (i + 1) % 3, q = (i + 2) % 3;
  const double ep = g.e[j][p][l], eq = g.e[j][q][l];
  // (e's components are zero when the corners' are equal, so they are compared only then.)
  if (ep == 0 && eq == 0 && format::at(t.v[(j + 1) % 3], p) == format::at(t.v[j], p) &&
      format::at(t.v[(j + 1) % 3], q) == format::at(t.v[j], q))
    return;
  std::array<double, 3> axis = {0, 0, 0};
  axis[p] = -eq, axis[q] = ep;
  file_test<a>(axis, g.lo[1 + 3 * j + i][l], g.hi[1 + 3 * j + i][l], margin, pending);
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

// The plane test and the nine edge tests of lane l, pending, for the dominant axis a (a template
// argument, so that where each test is filed is mostly known at compile time); true when the
// plane test is the first pending one and bounds the a index.
template <int a>
bool TriangleColumns::add_tests(const GridTriangle& t, const PreparedPair& g, int l,
                                PendingTests& pending) {
  const double m = extent_;
  const std::array<double, 3> n = {g.n[0][l], g.n[1][l], g.n[2][l]};
  file_test<a>(n, g.lo[0][l], g.hi[0][l], 2048 * kRoundoff * m * m * m, pending);
  const bool plane_first = pending.count == 1 && pending.level[0] == 2;
  for (int j = 0; j < 3; ++j) {
    add_edge_test<a, 0>(t, g, l, j, 256 * kRoundoff * m * m, pending);
    add_edge_test<a, 1>(t, g, l, j, 256 * kRoundoff * m * m, pending);
    add_edge_test<a, 2>(t, g, l, j, 256 * kRoundoff * m * m, pending);
  }
  return plane_first;
}

bool TriangleColumns::setup(const GridTriangle& t) {
  PreparedPair g;
  prepare(t, t, g);
  return setup(t, g, 0);
}

bool TriangleColumns::setup(const GridTriangle& t, const PreparedPair& g, int l) {
  t_ = t;
  if ((g.inside >> l & 1) == 0) return false;
  for (int k = 0; k < 3; ++k) {  // integers within +-2^40: exact conversions
    range_.lo[k] = std::int64_t(g.ceil_lo[k][l]) - 1, range_.hi[k] = std::int64_t(g.floor_hi[k][l]);
    origin_[k] = std::int64_t(g.floor_lo[k][l]);
  }
  extent_ = g.extent[l];
  const double n[3] = {g.n[0][l], g.n[1][l], g.n[2][l]};
  a_ = 0;
  for (int k = 1; k < 3; ++k)
    if (std::fabs(n[k]) > std::fabs(n[a_])) a_ = k;
  if (n[0] == 0 && n[1] == 0 && n[2] == 0)  // degenerate: walk along the longest extent
    for (int k = 0; k < 3; ++k)
      if (range_.hi[k] - range_.lo[k] > range_.hi[a_] - range_.lo[a_]) a_ = k;
  u_ = (a_ + 1) % 3, v_ = (a_ + 2) % 3;
  std::fill(std::begin(count_), std::end(count_), 0);
  sure_inset_ = 0;
  uncertain_all_ = empty_ = has_plane_ = false;
  PendingTests pending;
  const bool plane_first = a_ == 0   ? add_tests<0>(t, g, l, pending)
                           : a_ == 1 ? add_tests<1>(t, g, l, pending)
                                     : add_tests<2>(t, g, l, pending);
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
