// The window kernel (voxelize_window.hpp) with AVX-512 in single precision: sixteen floats per
// register (a 4x4x4 window's plane test in four registers, an edge test's 4x4 plane in one), the
// comparisons as k-masks chained through the tests. The bounds are widened by the float
// evaluation's error (window_float_bounds), so the decisions stay the predicate's.
#include "voxelize_window.hpp"

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

// kWindowRotation's rows as floats (lanes 0..3 used).
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
  return _cvtmask64_u64(_kunpackd_mask64(_mm512_kunpackw(m[3], m[2]), _mm512_kunpackw(m[1], m[0])));
}

// The float form of the tests: axes rounded to float, bounds from window_float_bounds.
struct FloatTests {
  float n[3], plane[4];
  float xp[9], xq[9], b[9][4];
};

KILN_AVX512_INLINE void float_tests(const WindowTests& w, double extent, FloatTests& f) {
  for (int a = 0; a < 3; ++a) f.n[a] = float(w.n[a]);
  window_float_bounds(w.plane_slab[0], w.plane_slab[1], w.plane_m, w.plane_r, extent, f.plane);
  for (int t = 0; t < 9; ++t) {
    f.xp[t] = float(w.xp[t]), f.xq[t] = float(w.xq[t]);
    window_float_bounds(w.slab_lo[t], w.slab_hi[t], w.edge_m, w.r[t], extent, f.b[t]);
  }
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
    within(x, f.b[t], maybe, sure);
  }
  return {expand_window_mask(i, _cvtmask16_u32(maybe)),
          expand_window_mask(i, _cvtmask16_u32(sure))};
}

KILN_AVX512 void window_masks_avx512(const WindowJob& job, WindowMasks* out) {
  WindowTests w;
  window_tests(job, w);
  FloatTests f;
  float_tests(w, job.extent, f);
  __m512 cen[3][2];
  for (int a = 0; a < 3; ++a)
    for (unsigned k = 0; k < job.windows[a]; ++k)
      cen[a][k] = _mm512_add_ps(_mm512_set1_ps(float(job.base[a] + 4 * k)),
                                _mm512_load_ps(kRotation16[job.s[a] & 3]));
  WindowMasks edges[3][2][2];  // per axis i and window pair (k_p, k_q)
  for (int i = 0; i < 3; ++i) {
    const int p = (i + 1) % 3, q = (i + 2) % 3;
    for (unsigned kp = 0; kp < job.windows[p]; ++kp)
      for (unsigned kq = 0; kq < job.windows[q]; ++kq)
        edges[i][kp][kq] = edge_masks(f, cen[p][kp], cen[q][kq], i);
  }
  for (unsigned kz = 0; kz < job.windows[2]; ++kz)
    for (unsigned ky = 0; ky < job.windows[1]; ++ky)
      for (unsigned kx = 0; kx < job.windows[0]; ++kx) {
        const __m512 c[3] = {cen[0][kx], cen[1][ky], cen[2][kz]};
        WindowMasks m = plane_masks(f, c);
        const WindowMasks* e[3] = {&edges[0][ky][kz], &edges[1][kz][kx], &edges[2][kx][ky]};
        for (const WindowMasks* x : e) m.maybe &= x->maybe, m.sure &= x->sure;
        out[kx + 2 * ky + 4 * kz] = m;
      }
}

}  // namespace

WindowKernel window_kernel_avx512() {
  return window_masks_avx512;
}

}  // namespace kiln::voxelize_detail

#else

namespace kiln::voxelize_detail {
WindowKernel window_kernel_avx512() {
  return nullptr;
}
}  // namespace kiln::voxelize_detail

#endif
