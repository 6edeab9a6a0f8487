// The surface voxelizer's inner loop: one triangle's voxels as runs along columns, decided by the
// separating-axis tests in closed form instead of voxel by voxel.
//
// Every one of the 13 axes of triangle_overlaps_box (Akenine-Moller 2001) is a slab test
// "c . X in [B_lo, B_hi]" on the voxel centre c, linear in c; these are also Schwarz & Seidel's
// (2010) plane and 2D edge-function tests. Along a column parallel to the axis `a` where the
// triangle's normal is largest, each test with a non-zero a-component bounds the centre's a
// coordinate to an interval, so a column's voxels are one run [lo, hi], computed with a few
// multiply-adds; tests with a zero a-component bound the columns (rows along v, then u). The box
// axes are the candidate range, which is exact.
//
// Exactness: the predicate evaluates each test in double with rounding, so it may differ from the
// exact-arithmetic test near the slab's boundary. Each test carries a margin `m` (see
// margin_of_* in voxelize_columns.cpp) that bounds the difference between the predicate's value
// and the exact value plus the error of our own evaluation; a voxel whose centre is farther than
// `m` inside every test is set, one farther than `m` outside some test is skipped, and the rest
// ("maybe") are decided by triangle_touches_voxel itself. So the output equals the predicate's
// voxel set exactly, and only voxels within ~1e-12 voxel of a boundary (or all voxels of a
// degenerate triangle) cost the full test. Corners must lie within 2^40 grid units of the
// origin (always so on a grid fitted to the scene); a triangle beyond that is skipped.
//
// Small triangles (candidate range at most kSmallWindow = 13 voxels on every axis, as most are on
// dense meshes: dragon_871k covers ~12 voxels per triangle at 2048^3) take walk_small: the same
// intervals, but each compared with the window's centres (exact half-integers) two at a time,
// giving a bit mask per test level instead of a rounded index range, and the voxels gathered per
// 4x4x4 leaf so that each leaf is written once. A voxel is then set when its centre lies in every
// sure interval and tested when it lies in every maybe interval: the same decisions as the
// column walk, so the same voxels.
//
// On CPUs with AVX2 or AVX-512, triangles whose candidate range is at most 12 voxels on every
// axis (most of a dense mesh's) take the brute-force window kernel instead (voxelize_window.hpp:
// every test on every voxel of 4x4x4 windows at once, no filing, no divisions); walk_small then
// serves only 13-voxel ranges there, and every small triangle elsewhere.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "kiln/compiler/voxelizer.hpp"
#include "voxelize_window.hpp"

namespace kiln::voxelize_detail {

struct VoxelRange {
  std::int64_t lo[3], hi[3];  // inclusive; empty when lo > hi on an axis
};
inline bool is_empty(const VoxelRange& r) {
  return r.lo[0] > r.hi[0] || r.lo[1] > r.hi[1] || r.lo[2] > r.hi[2];
}

// Voxels whose closed box can meet the triangle's bounding box, clipped to `clip`: exactly the
// voxels that pass the predicate's three box-axis tests (the subtractions there are exact near
// the boundary, Sterbenz), so no margin is needed on these axes.
VoxelRange candidate_range(const GridTriangle& t, const VoxelRange& clip);

// One slab test as an interval of the local centre coordinate x along its level's axis:
// x in [lo + qu * cu + qv * cv, hi + qu * cu + qv * cv] (cu, cv: the local centre coordinates of
// the column's u and v), widened by its margin m (maybe). The sure interval is the maybe interval
// narrowed by twice the triangle's largest margin (lo_m + 2 max m >= lo + m for every test), so
// only the maybe bounds are evaluated.
struct SlabInterval {
  double lo_m, hi_m, qu, qv;
};

// floor and ceil of a double within +-2^52 without libm calls (the baseline, SSE2, has no
// rounding instruction, so std::floor is a call there).
inline std::int64_t floor_to_int(double x) {
  const auto i = std::int64_t(x);
  return i - std::int64_t(double(i) > x);
}
inline std::int64_t ceil_to_int(double x) {
  const auto i = std::int64_t(x);
  return i + std::int64_t(double(i) < x);
}

// Indices [lo, hi] (local: voxel index minus the triangle's origin) with centres j + 0.5 within
// [x_lo, x_hi], clipped to [clip_lo, clip_hi].
[[gnu::always_inline]] inline void centre_range(double x_lo, double x_hi, std::int64_t clip_lo,
                                                std::int64_t clip_hi, std::int64_t& lo,
                                                std::int64_t& hi) {
  // Clamp first so the conversions never overflow (bounds may be huge or infinite).
  const double f_lo = std::clamp(x_lo - 0.5, double(clip_lo) - 1, double(clip_hi) + 1);
  const double f_hi = std::clamp(x_hi - 0.5, double(clip_lo) - 1, double(clip_hi) + 1);
  lo = std::max(clip_lo, ceil_to_int(f_lo));
  hi = std::min(clip_hi, floor_to_int(f_hi));
}

// Narrows the maybe interval [lo, hi] by `tests` at (cu, cv).
[[gnu::always_inline]] inline void narrow(const SlabInterval* tests, int count, double cu,
                                          double cv, double& lo, double& hi) {
  for (int k = 0; k < count; ++k) {
    const SlabInterval& s = tests[k];
    const double w = s.qu * cu + s.qv * cv;
    lo = std::max(lo, s.lo_m + w), hi = std::min(hi, s.hi_m + w);
  }
}

// Bits of the voxels k in `nibble` (bits 0..3) along axis a inside a 4x4x4 leaf (Morton order:
// bit spread(x) | spread(y) << 1 | spread(z) << 2), at the other two coordinates 0.
struct NibbleMasks {
  std::uint64_t masks[3][16];
};
constexpr std::uint32_t kSpread4[4] = {0, 1, 8, 9};  // spread_bits of 0..3
constexpr NibbleMasks make_nibble_masks() {
  NibbleMasks t{};
  for (int a = 0; a < 3; ++a)
    for (std::uint32_t n = 0; n < 16; ++n)
      for (std::uint32_t k = 0; k < 4; ++k)
        if (n >> k & 1) t.masks[a][n] |= std::uint64_t{1} << (kSpread4[k] << a);
  return t;
}
inline constexpr NibbleMasks kNibbleMasks = make_nibble_masks();

// The small-window walk: at most kSmallWindow voxels along every axis, so at most kWindowLeaves
// 4x4x4 leaves (the window may start anywhere in a leaf).
constexpr int kSmallWindow = 13;
constexpr int kWindowLeaves = (kSmallWindow + 3 + 3) / 4;
static_assert(kWindowLeaves * kWindowLeaves * kWindowLeaves <= 64, "one bit per leaf");

// A triangle's voxels in the (at most kWindowLeaves^3) leaves its small window reaches, gathered
// before they are reported so that each leaf is written once. One per TriangleColumns: report
// clears the words it used, so the next triangle starts empty without clearing them all.
class WindowLeaves {
 public:
  void start(const std::int64_t first[3]) {
    for (int k = 0; k < 3; ++k) base_[k] = first[k] >> 2;
  }
  // The voxels (g[u], g[v], g[a] + k) for the bits k of `bits` (g global, within the window),
  // which lie in the `span` leaves along a from g[a]'s (g[a] % 4 + the window's a size <= 4 span).
  template <int a, int span, int u = (a + 1) % 3, int v = (a + 2) % 3>
  void add(const std::int64_t g[3], unsigned bits) {
    constexpr int n = kWindowLeaves, stride[3] = {1, n, n * n};
    const int slot = int((g[u] >> 2) - base_[u]) * stride[u] +
                     int((g[v] >> 2) - base_[v]) * stride[v] +
                     int((g[a] >> 2) - base_[a]) * stride[a];
    const unsigned shift = kSpread4[g[u] & 3] << u | kSpread4[g[v] & 3] << v;
    const unsigned m = bits << (g[a] & 3);
    for (int l = 0; l < span; ++l) {
      const unsigned nibble = m >> (4 * l) & 15;
      words_[slot + l * stride[a]] |= kNibbleMasks.masks[a][nibble] << shift;
      used_ |= std::uint64_t(nibble != 0) << (slot + l * stride[a]);
    }
  }
  // leaf(g, bits) for every leaf with voxels (g: its first voxel, global), then empty again.
  template <class Leaf>
  [[gnu::always_inline]] void report(Leaf leaf) {
    constexpr int n = kWindowLeaves;
    for (std::uint64_t b = used_; b != 0; b &= b - 1) {
      const int slot = std::countr_zero(b);
      const std::int64_t g[3] = {(base_[0] + slot % n) * 4, (base_[1] + slot / n % n) * 4,
                                 (base_[2] + slot / (n * n)) * 4};
      leaf(g, words_[slot]);
      words_[slot] = 0;
    }
    used_ = 0;
  }

 private:
  std::int64_t base_[3] = {0, 0, 0};
  std::uint64_t words_[kWindowLeaves * kWindowLeaves * kWindowLeaves] = {};
  std::uint64_t used_ = 0;
};

// Local centres j + 0.5 of the indices lo..hi (at most kSmallWindow of them; pairs of them for
// SSE2), and the bits of those indices.
struct WindowAxis {
  double c[(kSmallWindow + 1) / 2 * 2];
  int pairs;
  unsigned valid;
};
[[gnu::always_inline]] inline WindowAxis window_axis(std::int64_t lo, std::int64_t hi) {
  WindowAxis w;
  const double first = double(lo) + 0.5;
  for (int k = 0; k < (kSmallWindow + 1) / 2 * 2; ++k) w.c[k] = first + k;
  w.pairs = int(hi - lo + 2) / 2;
  w.valid = (2u << (hi - lo)) - 1;
  return w;
}

// Bits k of the window's centres within [lo, hi]. The comparisons are exact.
inline unsigned centres_in(const WindowAxis& w, double lo, double hi) {
  unsigned bits = 0;
#if defined(__SSE2__)
  const __m128d l = _mm_set1_pd(lo), h = _mm_set1_pd(hi);
  for (int k = 0; k < w.pairs; ++k) {
    const __m128d x = _mm_loadu_pd(w.c + 2 * k);
    bits |= unsigned(_mm_movemask_pd(_mm_and_pd(_mm_cmpge_pd(x, l), _mm_cmple_pd(x, h))))
            << (2 * k);
  }
#else
  for (int k = 0; k < 2 * w.pairs; ++k) bits |= unsigned(w.c[k] >= lo && w.c[k] <= hi) << k;
#endif
  return bits & w.valid;
}

// centres_in [lo, hi] (maybe) and [lo + inset, hi - inset] (sure), in one pass and without
// branches on the bounds (which branch a window takes is unpredictable).
[[gnu::always_inline]] inline void centres_within(const WindowAxis& w, double lo, double hi,
                                                  double inset, unsigned& maybe, unsigned& sure) {
#if defined(__SSE2__)
  unsigned m = 0, s = 0;
  const __m128d l = _mm_set1_pd(lo), h = _mm_set1_pd(hi);
  const __m128d sl = _mm_set1_pd(lo + inset), sh = _mm_set1_pd(hi - inset);
  for (int k = 0; k < w.pairs; ++k) {
    const __m128d x = _mm_loadu_pd(w.c + 2 * k);
    m |= unsigned(_mm_movemask_pd(_mm_and_pd(_mm_cmpge_pd(x, l), _mm_cmple_pd(x, h)))) << (2 * k);
    s |= unsigned(_mm_movemask_pd(_mm_and_pd(_mm_cmpge_pd(x, sl), _mm_cmple_pd(x, sh)))) << (2 * k);
  }
  maybe = m & w.valid, sure = s & w.valid;
#else
  maybe = centres_in(w, lo, hi), sure = centres_in(w, lo + inset, hi - inset);
#endif
}

// The interval of `count` tests that depend on one centre coordinate only (cu: qv = 0, or cv:
// qu = 0; SlabInterval::*q: that coefficient), for every centre of the window at once (two at a
// time on SSE2): narrow's arithmetic (the other term adds a zero, which changes no bound), so the
// same bounds.
[[gnu::always_inline]] inline void axis_bounds(const SlabInterval* tests, int count,
                                               double SlabInterval::*q, const WindowAxis& w,
                                               double* lo, double* hi) {
#if defined(__SSE2__)
  for (int k = 0; k < w.pairs; ++k) {
    const __m128d cu = _mm_loadu_pd(w.c + 2 * k);
    __m128d l = _mm_set1_pd(-INFINITY), h = _mm_set1_pd(INFINITY);
    for (int t = 0; t < count; ++t) {
      const __m128d x = _mm_mul_pd(_mm_set1_pd(tests[t].*q), cu);
      l = _mm_max_pd(l, _mm_add_pd(_mm_set1_pd(tests[t].lo_m), x));
      h = _mm_min_pd(h, _mm_add_pd(_mm_set1_pd(tests[t].hi_m), x));
    }
    _mm_storeu_pd(lo + 2 * k, l), _mm_storeu_pd(hi + 2 * k, h);
  }
#else
  for (int k = 0; k < 2 * w.pairs; ++k) {
    lo[k] = -INFINITY, hi[k] = INFINITY;
    for (int t = 0; t < count; ++t) {
      const double x = tests[t].*q * w.c[k];
      lo[k] = std::max(lo[k], tests[t].lo_m + x), hi[k] = std::min(hi[k], tests[t].hi_m + x);
    }
  }
#endif
}

class TriangleColumns {
 public:
  /// window: the kernel for triangles whose candidate range is at most kWindowsPerAxis *
  /// kWindowSide voxels on every axis (voxelize_window.hpp), or nullptr: the column walk for
  /// every triangle (and dominant_axis / reach_along_a valid after every setup, as the binning
  /// needs).
  explicit TriangleColumns(WindowKernel window = nullptr) : window_(window) {}
  /// Prepares the tests; false when the triangle touches no voxel at all.
  bool setup(const GridTriangle& t);
  /// The candidate range (every voxel the predicate can accept lies in it).
  const VoxelRange& range() const { return range_; }
  int dominant_axis() const { return a_; }
  /// The inclusive range of `a` indices (global) the triangle may reach over the columns
  /// [u0, u1] x [v0, v1] (global indices): the plane test's maybe-interval over the rectangle.
  void reach_along_a(std::int64_t u0, std::int64_t u1, std::int64_t v0, std::int64_t v1,
                     std::int64_t& a0, std::int64_t& a1) const;
  /// Reports every voxel of `clip` that triangle_touches_voxel accepts, once: runs of voxels
  /// along the dominant axis as run(c, a, a1) (c: the first voxel, global; the run goes to
  /// c[a] = a1), a 4x4x4 leaf's voxels as leaf(g, bits) (g: the leaf's first voxel, global; bits
  /// in Morton order within the leaf), single voxels as voxel(x, y, z).
  template <class Run, class Leaf, class Voxel>
  void walk(const VoxelRange& clip, Run run, Leaf leaf, Voxel voxel);

 private:
  // Slab tests as add_test forms them, before the division by their level's axis component.
  struct PendingTests {
    static constexpr int kMax = 10;  // the plane and nine edge axes
    double lo[kMax + 1], hi[kMax + 1], k[kMax + 1], q1[kMax + 1], q2[kMax + 1],
        margin[kMax + 1];  // one more for pairs
    int level[kMax];
    int count = 0;
    void add(double l, double h, double kk, double a1, double a2, double m, int lv) {
      lo[count] = l, hi[count] = h, k[count] = kk, q1[count] = a1, q2[count] = a2;
      margin[count] = m, level[count++] = lv;
    }
  };
  bool place(const GridTriangle& t);
  template <int a>
  bool add_tests(const GridTriangle& t, const std::array<double, 3>* e,
                 const std::array<double, 3>& n, PendingTests& pending);
  template <int a>
  void add_test(const std::array<double, 3>& axis, double margin, PendingTests& pending);
  template <int a, int i>
  void add_edge_test(const GridTriangle& t, int j, const std::array<double, 3>& e, double margin,
                     PendingTests& pending);
  template <int a>
  void file_test(const std::array<double, 3>& axis, double lo, double hi, double margin,
                 PendingTests& pending);
  void commit_tests(PendingTests& pending, bool plane_first);
  void divide_tests(const PendingTests& p, int i, SlabInterval* out, double* m) const;
  void file_interval(const SlabInterval& s, int level, int* constant);
  void fill_v_table(std::int64_t v0, std::int64_t v1);
  // walk for a local range at most kSmallWindow wide on every axis: each test's voxels as bit
  // masks of the window's centres along a (comparisons, no conversions; no v table).
  // (a: the dominant axis, a template argument so that the leaf slots and shifts are constants.)
  // (span: the leaves along a the window reaches, kWindowLeaves or fewer, so that a column's
  // voxels are added without a loop over leaves they cannot reach.)
  template <int a, int span, class Leaf, class Voxel>
  void walk_small(const VoxelRange& r, Leaf leaf, Voxel voxel);
  // walk for a window triangle (windowed_): the kernel's masks, the predicate on the lanes
  // between them, the set lanes split into their leaves. r: the clipped range, local.
  template <class Leaf>
  void walk_window(const VoxelRange& r, Leaf leaf);
  template <class Leaf>
  void window_leaves(const WindowMasks& masks, std::uint64_t box, const unsigned* s,
                     const std::int64_t* at, Leaf leaf) const;
  template <int a, class Leaf, class Voxel>
  [[gnu::noinline]] void walk_small_any(const VoxelRange& r, Leaf leaf, Voxel voxel) {
    // The window's a range, from the start of its first leaf (global index modulo 4).
    const std::int64_t reach = ((r.lo[a] + origin_[a]) & 3) + r.hi[a] - r.lo[a];
    if (reach < 8)
      walk_small<a, 2>(r, leaf, voxel);
    else
      walk_small<a, kWindowLeaves>(r, leaf, voxel);
  }
  // The column walk over the local range r (runs along a, rounded to indices per column).
  template <class Run, class Voxel>
  void walk_columns(const VoxelRange& r, Run run, Voxel voxel);
  template <int level>
  [[gnu::always_inline]] void level_bits(double cu, double cv, const WindowAxis& w, unsigned& maybe,
                                         unsigned& sure) const {
    double lo = -INFINITY, hi = INFINITY;
    narrow(tests_[level], kSmallCount[level], cu, cv, lo, hi);
    centres_within(w, lo, hi, sure_inset_, maybe, sure);
  }

  WindowKernel window_ = nullptr;
  bool windowed_ = false;  // this triangle takes window_
  GridTriangle t_{};
  VoxelRange range_{};
  int a_ = 2, u_ = 0, v_ = 1;
  std::int64_t origin_[3] = {0, 0, 0};  // local origin (integers), per axis
  std::array<double, 3> p_[3]{};        // corners minus the origin
  double extent_ = 1;                   // M: bounds |corner - centre| over candidate voxels
  double sure_inset_ = 0;               // twice the largest margin of the tests
  bool uncertain_all_ = false;          // every voxel is decided by the exact predicate
  bool empty_ = false;                  // a test separates every voxel
  bool has_plane_ = false;              // the plane test bounds the a index (plane_)
  SlabInterval plane_{};
  // Tests per level: [0] bound the u index, [1] the v index per row, [2] the a index per column.
  // After setup, the a-index tests that depend on cu only move to [3] (once per row) and those
  // on cv only to [4] (once per v index, tabled): a column then evaluates only [2], mostly the
  // plane, since an edge axis cross(unit u, e) has no u component and cross(unit v, e) no v.
  SlabInterval tests_[5][10]{};
  int count_[5] = {0, 0, 0, 0, 0};
  // walk_small evaluates kSmallCount[level] tests per level, whatever count_ says: setup pads
  // the levels with tests that pass everything (small_ is false when a level holds more).
  static constexpr int kSmallCount[5] = {1, 3, 1, 4, 3};
  bool small_ = false;
  WindowLeaves window_leaves_;
  std::vector<double> v_table_;  // per v index of the walk: lo_m, hi_m of [4]
};

// The a-interval of the tests that depend on cv only, per local v index in [v0, v1].
[[gnu::always_inline]] inline void TriangleColumns::fill_v_table(std::int64_t v0, std::int64_t v1) {
  v_table_.resize(2 * std::size_t(v1 - v0 + 1));
  for (std::int64_t iv = v0; iv <= v1; ++iv) {
    double* t = &v_table_[2 * std::size_t(iv - v0)];
    t[0] = -INFINITY, t[1] = INFINITY;
    narrow(tests_[4], count_[4], 0, double(iv) + 0.5, t[0], t[1]);
  }
}

template <int a, int span, class Leaf, class Voxel>
void TriangleColumns::walk_small(const VoxelRange& r, Leaf leaf, Voxel voxel) {
  constexpr int u = (a + 1) % 3, v = (a + 2) % 3;
  const WindowAxis wu = window_axis(r.lo[u], r.hi[u]), wv = window_axis(r.lo[v], r.hi[v]),
                   wa = window_axis(r.lo[a], r.hi[a]);
  unsigned u_maybe, u_sure;
  level_bits<0>(0, 0, wu, u_maybe, u_sure);
  if (uncertain_all_) u_sure = 0;
  // Per v: the a interval of [4]; per row: the v interval of [1] and the a interval of [3].
  constexpr int kPadded = (kSmallWindow + 1) / 2 * 2;
  double a_lo_v[kPadded], a_hi_v[kPadded], v_lo_u[kPadded], v_hi_u[kPadded], a_lo_u[kPadded],
      a_hi_u[kPadded];
  axis_bounds(tests_[4], kSmallCount[4], &SlabInterval::qv, wv, a_lo_v, a_hi_v);
  axis_bounds(tests_[1], kSmallCount[1], &SlabInterval::qu, wu, v_lo_u, v_hi_u);
  axis_bounds(tests_[3], kSmallCount[3], &SlabInterval::qu, wu, a_lo_u, a_hi_u);
  std::int64_t c[3] = {r.lo[0] + origin_[0], r.lo[1] + origin_[1], r.lo[2] + origin_[2]};
  WindowLeaves& leaves = window_leaves_;
  leaves.start(c);
  for (unsigned bu = u_maybe; bu != 0; bu &= bu - 1) {
    const int ku = std::countr_zero(bu);
    const double cu = wu.c[ku];
    unsigned v_maybe, v_sure;
    centres_within(wv, v_lo_u[ku], v_hi_u[ku], sure_inset_, v_maybe, v_sure);
    if ((u_sure >> ku & 1) == 0) v_sure = 0;
    const double row_lo = a_lo_u[ku], row_hi = a_hi_u[ku];
    c[u] = r.lo[u] + ku + origin_[u];
    for (unsigned bv = v_maybe; bv != 0; bv &= bv - 1) {
      const int kv = std::countr_zero(bv);
      double lo = std::max(row_lo, a_lo_v[kv]), hi = std::min(row_hi, a_hi_v[kv]);
      narrow(tests_[2], kSmallCount[2], cu, wv.c[kv], lo, hi);
      unsigned maybe, sure;
      centres_within(wa, lo, hi, sure_inset_, maybe, sure);
      sure &= 0u - (v_sure >> kv & 1);
      c[v] = r.lo[v] + kv + origin_[v];
      leaves.add<a, span>(c, sure);
      for (unsigned b = maybe & ~sure; b != 0; b &= b - 1) {  // near a bound: rare
        std::int64_t x[3] = {c[0], c[1], c[2]};
        x[a] += std::countr_zero(b);
        const auto gx = std::uint32_t(x[0]), gy = std::uint32_t(x[1]), gz = std::uint32_t(x[2]);
        if (triangle_touches_voxel(t_, gx, gy, gz)) voxel(gx, gy, gz);
      }
    }
  }
  leaves.report(leaf);
}

template <class Leaf>
void TriangleColumns::walk_window(const VoxelRange& r, Leaf leaf) {
  WindowJob job{&t_, p_, extent_, {}, {}, {}};
  std::int64_t first[3], from[3], to[3];  // first leaf (global); the clipped range in the windows
  for (int k = 0; k < 3; ++k) {
    const std::int64_t lo = range_.lo[k] - origin_[k];  // local, as r
    job.s[k] = unsigned(range_.lo[k] & 3), first[k] = range_.lo[k] & ~std::int64_t{3};
    job.base[k] = double(lo) + 0.5;
    job.windows[k] = unsigned(range_.hi[k] - range_.lo[k]) / kWindowSide + 1;
    from[k] = r.lo[k] - lo, to[k] = r.hi[k] - lo;
  }
  WindowMasks masks[kWindowsMax];
  window_(job, masks);
  for (unsigned kz = 0; kz < job.windows[2]; ++kz)
    for (unsigned ky = 0; ky < job.windows[1]; ++ky)
      for (unsigned kx = 0; kx < job.windows[0]; ++kx) {
        const unsigned k[3] = {kx, ky, kz};
        std::uint64_t box = ~std::uint64_t{0};
        std::int64_t at[3];  // this window's first leaf
        for (int a = 0; a < 3; ++a) {
          const std::int64_t lo = std::max<std::int64_t>(from[a] - 4 * k[a], 0),
                             hi = std::min<std::int64_t>(to[a] - 4 * k[a], 3);
          box = lo <= hi ? box & kWindowLaneMasks.box[a][job.s[a]][lo][hi] : 0;
          at[a] = first[a] + 4 * k[a];
        }
        window_leaves(masks[kx + kWindowsPerAxis * (ky + kWindowsPerAxis * kz)], box, job.s, at,
                      leaf);
      }
}

// One window's voxels: the kernel's sure lanes and the maybe lanes the predicate accepts, within
// `box`, reported per leaf (at: the window's first leaf, global; s: the range's first voxel & 3).
template <class Leaf>
void TriangleColumns::window_leaves(const WindowMasks& masks, std::uint64_t box, const unsigned* s,
                                    const std::int64_t* at, Leaf leaf) const {
  const std::uint64_t maybe = masks.maybe & box;
  std::uint64_t set = masks.sure & maybe;
  for (std::uint64_t b = maybe & ~set; b != 0; b &= b - 1) {  // near a bound: rare
    const int lane = std::countr_zero(b);
    std::uint32_t x[3];
    for (int k = 0; k < 3; ++k) {
      const int c = window_coord(lane, k);
      x[k] = std::uint32_t(at[k] + c + (unsigned(c) < s[k] ? 4 : 0));
    }
    if (triangle_touches_voxel(t_, x[0], x[1], x[2])) set |= std::uint64_t{1} << lane;
  }
  if (set == 0) return;
  // Along each axis, the leaves (first: lanes with coord >= s) that hold set lanes: those lie in
  // the clip, so every leaf of the loop does (some may be empty: leaf must accept zero bits).
  std::uint64_t sel[3][2];
  int from[3], to[3];
  for (int k = 0; k < 3; ++k) {
    sel[k][0] = kWindowLaneMasks.first_leaf[k][s[k]], sel[k][1] = ~sel[k][0];
    from[k] = (set & sel[k][0]) != 0 ? 0 : 1, to[k] = (set & sel[k][1]) != 0 ? 1 : 0;
  }
  for (int lz = from[2]; lz <= to[2]; ++lz)
    for (int ly = from[1]; ly <= to[1]; ++ly)
      for (int lx = from[0]; lx <= to[0]; ++lx) {
        const std::int64_t g[3] = {at[0] + 4 * lx, at[1] + 4 * ly, at[2] + 4 * lz};
        leaf(g, set & sel[0][lx] & sel[1][ly] & sel[2][lz]);
      }
}

template <class Run, class Leaf, class Voxel>
void TriangleColumns::walk(const VoxelRange& clip, Run run, Leaf leaf, Voxel voxel) {
  VoxelRange r;
  for (int k = 0; k < 3; ++k)
    r.lo[k] = std::max(range_.lo[k], clip.lo[k]) - origin_[k],
    r.hi[k] = std::min(range_.hi[k], clip.hi[k]) - origin_[k];
  if (is_empty(r)) return;
  if (windowed_)
    walk_window(r, leaf);
  else if (small_ && r.hi[0] - r.lo[0] < kSmallWindow && r.hi[1] - r.lo[1] < kSmallWindow &&
           r.hi[2] - r.lo[2] < kSmallWindow)
    a_ == 0   ? walk_small_any<0>(r, leaf, voxel)
    : a_ == 1 ? walk_small_any<1>(r, leaf, voxel)
              : walk_small_any<2>(r, leaf, voxel);
  else
    walk_columns(r, run, voxel);
}

template <class Run, class Voxel>
void TriangleColumns::walk_columns(const VoxelRange& r, Run run, Voxel voxel) {
  const int a = a_, u = u_, v = v_;
  const double inset = sure_inset_;
  double lo = -INFINITY, hi = INFINITY;
  std::int64_t u0, u1;
  narrow(tests_[0], count_[0], 0, 0, lo, hi);
  centre_range(lo, hi, r.lo[u], r.hi[u], u0, u1);
  const double u_sure_lo = lo + inset, u_sure_hi = hi - inset;
  fill_v_table(r.lo[v], r.hi[v]);
  std::int64_t c[3];
  auto exact = [&](std::int64_t from, std::int64_t to) {
    for (std::int64_t ia = from; ia <= to; ++ia) {
      c[a] = ia + origin_[a];
      const auto x = std::uint32_t(c[0]), y = std::uint32_t(c[1]), z = std::uint32_t(c[2]);
      if (triangle_touches_voxel(t_, x, y, z)) voxel(x, y, z);
    }
  };
  for (std::int64_t iu = u0; iu <= u1; ++iu) {
    const double cu = double(iu) + 0.5;
    const bool sure_u = !uncertain_all_ && cu >= u_sure_lo && cu <= u_sure_hi;
    std::int64_t v0, v1;
    lo = -INFINITY, hi = INFINITY;
    narrow(tests_[1], count_[1], cu, 0, lo, hi);
    centre_range(lo, hi, r.lo[v], r.hi[v], v0, v1);
    const double v_sure_lo = lo + inset, v_sure_hi = hi - inset;
    double row_lo = -INFINITY, row_hi = INFINITY;
    narrow(tests_[3], count_[3], cu, 0, row_lo, row_hi);
    c[u] = iu + origin_[u];
    for (std::int64_t iv = v0; iv <= v1; ++iv) {
      const double cv = double(iv) + 0.5;
      const double* t = &v_table_[2 * std::size_t(iv - r.lo[v])];
      lo = std::max(row_lo, t[0]), hi = std::min(row_hi, t[1]);
      narrow(tests_[2], count_[2], cu, cv, lo, hi);
      std::int64_t a0, a1;
      centre_range(lo, hi, r.lo[a], r.hi[a], a0, a1);
      if (a0 > a1) continue;
      c[v] = iv + origin_[v];
      // The run is sure when its end voxels are (the sure interval is convex): two comparisons
      // instead of a second pair of conversions.
      const bool sure_uv = sure_u && cv >= v_sure_lo && cv <= v_sure_hi;
      const double s_lo = lo + inset, s_hi = hi - inset;
      if (sure_uv && double(a0) + 0.5 >= s_lo && double(a1) + 0.5 <= s_hi) {
        c[a] = a0 + origin_[a];
        run(c, a, a1 + origin_[a]);
        continue;
      }
      for (std::int64_t ia = a0; ia <= a1; ++ia) {  // near a bound: rare
        const double ca = double(ia) + 0.5;
        if (sure_uv && ca >= s_lo && ca <= s_hi) {
          c[a] = ia + origin_[a];
          voxel(std::uint32_t(c[0]), std::uint32_t(c[1]), std::uint32_t(c[2]));
        } else {
          exact(ia, ia);
        }
      }
    }
  }
}

}  // namespace kiln::voxelize_detail
