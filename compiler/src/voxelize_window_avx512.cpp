// The window kernel (voxelize_window.hpp) with AVX-512 in single precision: sixteen floats per
// register (a 4x4x4 window's plane test in four registers, an edge test's 4x4 plane in one), the
// comparisons as k-masks chained through the tests. The bounds are widened by the float
// evaluation's error (window_float_bounds), so the decisions stay the predicate's.
#include "voxelize_window.hpp"

#include <algorithm>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>

#define KILN_AVX512 __attribute__((target("avx2,fma,avx512f,avx512vl,avx512dq,avx512bw")))
#define KILN_AVX512_INLINE \
  __attribute__((target("avx2,fma,avx512f,avx512vl,avx512dq,avx512bw"), always_inline)) inline

namespace kiln::voxelize_detail {

namespace {

// Index patterns over 16 lanes. 3D lanes 16v + l: l's bits are x0, y0, z0, x1 and v's y1, z1, so
// coord_x has one pattern and coord_y, coord_z two each (by v's bit). 2D lanes l: p0, q0, p1, q1.
alignas(64) constexpr int kPatternX[16] = {0, 1, 0, 1, 0, 1, 0, 1, 2, 3, 2, 3, 2, 3, 2, 3};
alignas(64) constexpr int kPatternY[2][16] = {{0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1},
                                              {2, 2, 3, 3, 2, 2, 3, 3, 2, 2, 3, 3, 2, 2, 3, 3}};
alignas(64) constexpr int kPatternZ[2][16] = {{0, 0, 0, 0, 1, 1, 1, 1, 0, 0, 0, 0, 1, 1, 1, 1},
                                              {2, 2, 2, 2, 3, 3, 3, 3, 2, 2, 2, 2, 3, 3, 3, 3}};
alignas(64) constexpr int kPatternP[16] = {0, 1, 0, 1, 2, 3, 2, 3, 0, 1, 0, 1, 2, 3, 2, 3};
alignas(64) constexpr int kPatternQ[16] = {0, 0, 1, 1, 0, 0, 1, 1, 2, 2, 3, 3, 2, 2, 3, 3};

// Per s: the centre offsets (coord - s) & 3 of coord = 0..3 (lanes 0..3 used).
alignas(64) constexpr float kRotation16[4][16] = {
    {0, 1, 2, 3}, {3, 0, 1, 2}, {2, 3, 0, 1}, {1, 2, 3, 0}};

// The centres cen[0..3] of one axis in the lanes' pattern: lane l takes cen[index[l]].
KILN_AVX512_INLINE __m512 spread(__m512 cen, const int (&index)[16]) {
  return _mm512_maskz_permutexvar_ps(0xffff, _mm512_load_si512(index), cen);
}

// maybe &= b[0] <= x <= b[1], sure &= b[2] <= x <= b[3].
KILN_AVX512_INLINE void within(__m512 x, const float* b, __mmask16& maybe, __mmask16& sure) {
  maybe = _mm512_mask_cmp_ps_mask(maybe, x, _mm512_set1_ps(b[0]), _CMP_GE_OQ);
  maybe = _mm512_mask_cmp_ps_mask(maybe, x, _mm512_set1_ps(b[1]), _CMP_LE_OQ);
  sure = _mm512_mask_cmp_ps_mask(sure, x, _mm512_set1_ps(b[2]), _CMP_GE_OQ);
  sure = _mm512_mask_cmp_ps_mask(sure, x, _mm512_set1_ps(b[3]), _CMP_LE_OQ);
}

KILN_AVX512_INLINE std::uint64_t join(const __mmask16* m) {
  // _mm512_kunpackd, not _kunpackd_mask64: clang 14 (the fuzz build) lacks the latter.
  return _cvtmask64_u64(_mm512_kunpackd(_mm512_kunpackw(m[3], m[2]), _mm512_kunpackw(m[1], m[0])));
}

// The float form of the tests: axes rounded to float, bounds from window_float_bounds' formula;
// the edge tests t = 3i + j in entries 0..8 (9..15: copies of test 8).
struct FloatTests {
  float n[3], plane[4];
  alignas(32) float xp[16], xq[16], lo[16], hi[16], slo[16], shi[16];
};

// Flat indices (3 corner + axis, < 9) per edge test t = 3i + j, a = i + 1, b = i + 2: corner j
// along b and a (also e_j's components: xp = -e_j[b], xq = e_j[a]), corner j + 2 and j + 1.
struct EdgeIndex {
  alignas(64) long long jb[16], ja[16], kb[16], ka[16], nb[16], na[16];
};
constexpr EdgeIndex make_edge_index() {
  EdgeIndex x{};
  for (int t = 0; t < 16; ++t) {
    const int i = std::min(t, 8) / 3, j = std::min(t, 8) % 3, a = (i + 1) % 3, b = (i + 2) % 3;
    x.jb[t] = 3 * j + b, x.ja[t] = 3 * j + a;
    x.kb[t] = 3 * ((j + 2) % 3) + b, x.ka[t] = 3 * ((j + 2) % 3) + a;
    x.nb[t] = 3 * ((j + 1) % 3) + b, x.na[t] = 3 * ((j + 1) % 3) + a;
  }
  return x;
}
constexpr EdgeIndex kEdgeIndex = make_edge_index();

// Nine doubles in registers: lanes 0..7 of lo, lane 0 of hi.
struct Nine {
  __m512d lo, hi;
};
KILN_AVX512_INLINE Nine load_nine(const double* flat) {
  return {_mm512_loadu_pd(flat), _mm512_maskz_loadu_pd(1, flat + 8)};
}
// x[index[l]] for the eight lanes l.
KILN_AVX512_INLINE __m512d pick(const Nine& x, const long long* index) {
  return _mm512_permutex2var_pd(x.lo, _mm512_load_si512(index), x.hi);
}

// Edge tests 8h..8h+7 as window_tests forms them (the projections of corners j and j + 2 only:
// corner j + 1's exact projection equals corner j's, so the min and max carry the same error
// bound), with window_float_bounds' bounds. p, e, v: corners (local), edges, corners (global).
KILN_AVX512_INLINE void float_edges(const Nine& p, const Nine& e, const Nine& v, int h, double m,
                                    double extent, FloatTests& f) {
  const EdgeIndex& x = kEdgeIndex;
  const __m512d sign = _mm512_set1_pd(-0.0), zero = _mm512_setzero_pd();
  const __m512d xp = _mm512_xor_pd(pick(e, x.jb + 8 * h), sign), xq = pick(e, x.ja + 8 * h);
  const __m512d d1 = _mm512_add_pd(_mm512_mul_pd(pick(p, x.ja + 8 * h), xp),
                                   _mm512_mul_pd(pick(p, x.jb + 8 * h), xq));
  const __m512d d3 = _mm512_add_pd(_mm512_mul_pd(pick(p, x.ka + 8 * h), xp),
                                   _mm512_mul_pd(pick(p, x.kb + 8 * h), xq));
  const __m512d r =
      _mm512_mul_pd(_mm512_set1_pd(0.5), _mm512_add_pd(_mm512_abs_pd(xp), _mm512_abs_pd(xq)));
  __m512d lo = _mm512_sub_pd(_mm512_maskz_min_pd(0xff, d1, d3), r),
          hi = _mm512_add_pd(_mm512_maskz_max_pd(0xff, d1, d3), r);
  // Skipped: an edge parallel to axis i (its corners equal along a and b).
  __mmask8 skip = _mm512_cmp_pd_mask(xp, zero, _CMP_EQ_OQ);
  skip = _mm512_mask_cmp_pd_mask(skip, xq, zero, _CMP_EQ_OQ);
  skip = _mm512_mask_cmp_pd_mask(skip, pick(v, x.na + 8 * h), pick(v, x.ja + 8 * h), _CMP_EQ_OQ);
  skip = _mm512_mask_cmp_pd_mask(skip, pick(v, x.nb + 8 * h), pick(v, x.jb + 8 * h), _CMP_EQ_OQ);
  lo = _mm512_mask_blend_pd(skip, lo, _mm512_set1_pd(-1e30));
  hi = _mm512_mask_blend_pd(skip, hi, _mm512_set1_pd(1e30));
  const __m512d err =
      _mm512_add_pd(_mm512_set1_pd(m), _mm512_mul_pd(_mm512_set1_pd(12 * 0x1p-24 * extent), r));
  const __m512d mf = _mm512_add_pd(
      err,
      _mm512_mul_pd(
          _mm512_set1_pd(0x1p-22),
          _mm512_add_pd(_mm512_maskz_max_pd(0xff, _mm512_abs_pd(lo), _mm512_abs_pd(hi)), err)));
  _mm256_store_ps(f.xp + 8 * h, _mm512_maskz_cvtpd_ps(0xff, xp));
  _mm256_store_ps(f.xq + 8 * h, _mm512_maskz_cvtpd_ps(0xff, xq));
  _mm256_store_ps(f.lo + 8 * h, _mm512_maskz_cvtpd_ps(0xff, _mm512_sub_pd(lo, mf)));
  _mm256_store_ps(f.hi + 8 * h, _mm512_maskz_cvtpd_ps(0xff, _mm512_add_pd(hi, mf)));
  _mm256_store_ps(f.slo + 8 * h, _mm512_maskz_cvtpd_ps(0xff, _mm512_add_pd(lo, mf)));
  _mm256_store_ps(f.shi + 8 * h, _mm512_maskz_cvtpd_ps(0xff, _mm512_sub_pd(hi, mf)));
}

KILN_AVX512_INLINE void float_tests(const WindowJob& job, FloatTests& f) {
  WindowPlane w;
  window_plane(job, w);
  for (int a = 0; a < 3; ++a) f.n[a] = float(w.n[a]);
  window_float_bounds(w.slab[0], w.slab[1], w.m, w.r, job.extent, f.plane);
  static_assert(sizeof(std::array<double, 3>) == 3 * sizeof(double) &&
                sizeof(format::Double3) == 3 * sizeof(double));
  const Nine p = load_nine(job.p[0].data()), v = load_nine(&job.t->v[0].x);
  alignas(64) static constexpr long long kNext[16] = {3, 4, 5, 6, 7, 8, 0, 1,
                                                      2, 2, 2, 2, 2, 2, 2, 2};
  const Nine e = {_mm512_sub_pd(pick(p, kNext), p.lo), _mm512_sub_pd(pick(p, kNext + 8), p.hi)};
  const double m_edge = 256 * 0x1p-53 * job.extent * job.extent;
  float_edges(p, e, v, 0, m_edge, job.extent, f);
  float_edges(p, e, v, 1, m_edge, job.extent, f);
}

KILN_AVX512_INLINE WindowMasks plane_masks(const FloatTests& f, const __m512* cen) {
  const __m512 px = _mm512_mul_ps(_mm512_set1_ps(f.n[0]), spread(cen[0], kPatternX));
  __m512 py[2], pz[2];
  for (int b = 0; b < 2; ++b)
    py[b] = _mm512_mul_ps(_mm512_set1_ps(f.n[1]), spread(cen[1], kPatternY[b])),
    pz[b] = _mm512_mul_ps(_mm512_set1_ps(f.n[2]), spread(cen[2], kPatternZ[b]));
  __mmask16 maybe[4], sure[4];
  for (int v = 0; v < 4; ++v) {
    const __m512 x = _mm512_add_ps(_mm512_add_ps(px, py[v & 1]), pz[v >> 1]);
    maybe[v] = sure[v] = 0xffff;
    within(x, f.plane, maybe[v], sure[v]);
  }
  return {join(maybe), join(sure)};
}

// The three edge tests of axis i on the window pair's plane (i + 1, i + 2), expanded along i.
KILN_AVX512_INLINE WindowMasks edge_masks(const FloatTests& f, __m512 cen_p, __m512 cen_q, int i) {
  const __m512 cp = spread(cen_p, kPatternP), cq = spread(cen_q, kPatternQ);
  __mmask16 maybe = 0xffff, sure = 0xffff;
  for (int t = 3 * i; t < 3 * i + 3; ++t) {
    const __m512 x = _mm512_add_ps(_mm512_mul_ps(_mm512_set1_ps(f.xp[t]), cp),
                                   _mm512_mul_ps(_mm512_set1_ps(f.xq[t]), cq));
    const float b[4] = {f.lo[t], f.hi[t], f.slo[t], f.shi[t]};
    within(x, b, maybe, sure);
  }
  return {expand_window_mask(i, _cvtmask16_u32(maybe)),
          expand_window_mask(i, _cvtmask16_u32(sure))};
}

// The voxels (lanes) of the window whose first voxel has local centre coordinate `base`, with
// s = g & 3 (voxelize_window.hpp: lane order).
KILN_AVX512_INLINE __m512 window_centres(float base, unsigned s) {
  return _mm512_add_ps(_mm512_set1_ps(base), _mm512_load_ps(kRotation16[s & 3]));
}

#define KILN_WINDOW_ENTRY KILN_AVX512
#include "voxelize_window_driver.inl"
#undef KILN_WINDOW_ENTRY

}  // namespace

WindowKernel window_kernel_avx512() {
  return window_masks<__m512>;
}

}  // namespace kiln::voxelize_detail

#else

namespace kiln::voxelize_detail {
WindowKernel window_kernel_avx512() {
  return nullptr;
}
}  // namespace kiln::voxelize_detail

#endif
