// The window kernel (voxelize_window.hpp) with AVX-512: eight doubles per register, the
// comparisons as k-masks chained through the tests (a lane fails once it fails a test).
#include "voxelize_window.hpp"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>

#define KILN_AVX512 __attribute__((target("avx2,fma,avx512f,avx512vl,avx512dq,avx512bw")))
#define KILN_AVX512_INLINE \
  __attribute__((target("avx2,fma,avx512f,avx512vl,avx512dq,avx512bw"), always_inline)) inline

namespace kiln::voxelize_detail {

namespace {

// The centres cen[k] (k = 0..3) of one axis in the lanes' pattern: lane l takes cen[index[l]].
// (cen: cen[0..3] twice.)
KILN_AVX512_INLINE __m512d spread(__m512d cen, const long long (&index)[8]) {
  return _mm512_maskz_permutexvar_pd(0xff, _mm512_loadu_si512(index), cen);
}

// kWindowRotation's rows twice, for eight lanes.
alignas(64) constexpr double kRotation8[4][8] = {{0, 1, 2, 3, 0, 1, 2, 3},
                                                 {3, 0, 1, 2, 3, 0, 1, 2},
                                                 {2, 3, 0, 1, 2, 3, 0, 1},
                                                 {1, 2, 3, 0, 1, 2, 3, 0}};

// Index patterns. 3D lanes 8v + l: coord_a = (l >> a & 1) | (v >> a & 1) << 1, so each axis has
// two patterns (by v's bit a). 2D lanes 8h + l (l: p0 | q0 << 1 | p1 << 2, h: q1).
alignas(64) constexpr long long kPattern3[3][2][8] = {
    {{0, 1, 0, 1, 0, 1, 0, 1}, {2, 3, 2, 3, 2, 3, 2, 3}},
    {{0, 0, 1, 1, 0, 0, 1, 1}, {2, 2, 3, 3, 2, 2, 3, 3}},
    {{0, 0, 0, 0, 1, 1, 1, 1}, {2, 2, 2, 2, 3, 3, 3, 3}}};
alignas(64) constexpr long long kPatternP[8] = {0, 1, 0, 1, 2, 3, 2, 3};
alignas(64) constexpr long long kPatternQ[2][8] = {{0, 0, 1, 1, 0, 0, 1, 1},
                                                   {2, 2, 3, 3, 2, 2, 3, 3}};

// maybe &= lo <= x <= hi, sure &= slo <= x <= shi.
KILN_AVX512_INLINE void within(__m512d x, const double* b, __mmask8& maybe, __mmask8& sure) {
  maybe = _mm512_mask_cmp_pd_mask(maybe, x, _mm512_set1_pd(b[0]), _CMP_GE_OQ);
  maybe = _mm512_mask_cmp_pd_mask(maybe, x, _mm512_set1_pd(b[1]), _CMP_LE_OQ);
  sure = _mm512_mask_cmp_pd_mask(sure, x, _mm512_set1_pd(b[2]), _CMP_GE_OQ);
  sure = _mm512_mask_cmp_pd_mask(sure, x, _mm512_set1_pd(b[3]), _CMP_LE_OQ);
}

// Eight masks of eight lanes (m[v]: lanes 8v..8v+7) as one 64-bit mask, in mask registers.
KILN_AVX512_INLINE std::uint64_t join(const __mmask8* m) {
  const __mmask16 m01 = _mm512_kunpackb(m[1], m[0]), m23 = _mm512_kunpackb(m[3], m[2]),
                  m45 = _mm512_kunpackb(m[5], m[4]), m67 = _mm512_kunpackb(m[7], m[6]);
  return _cvtmask64_u64(_kunpackd_mask64(_kunpackw_mask32(m67, m45), _kunpackw_mask32(m23, m01)));
}

KILN_AVX512_INLINE WindowMasks plane_masks(const WindowTests& w, const __m512d* cen) {
  __m512d part[3][2];
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 2; ++b)
      part[a][b] = _mm512_mul_pd(_mm512_set1_pd(w.n[a]), spread(cen[a], kPattern3[a][b]));
  __mmask8 maybe[8], sure[8];
  for (int v = 0; v < 8; ++v) {
    const __m512d x =
        _mm512_add_pd(_mm512_add_pd(part[0][v & 1], part[1][v >> 1 & 1]), part[2][v >> 2 & 1]);
    maybe[v] = sure[v] = 0xff;
    within(x, w.plane, maybe[v], sure[v]);
  }
  return {join(maybe), join(sure)};
}

// The three edge tests of axis i, as 16-bit masks of the plane (i + 1, i + 2).
KILN_AVX512_INLINE void edge_masks(const WindowTests& w, const __m512d* cen, int i,
                                   unsigned& maybe16, unsigned& sure16) {
  const __m512d cp = spread(cen[(i + 1) % 3], kPatternP);
  const __m512d cq0 = spread(cen[(i + 2) % 3], kPatternQ[0]),
                cq1 = spread(cen[(i + 2) % 3], kPatternQ[1]);
  __mmask8 m0 = 0xff, m1 = 0xff, s0 = 0xff, s1 = 0xff;
  for (int t = 3 * i; t < 3 * i + 3; ++t) {
    const __m512d xq = _mm512_set1_pd(w.xq[t]), a = _mm512_mul_pd(_mm512_set1_pd(w.xp[t]), cp);
    const double b[4] = {w.lo[t], w.hi[t], w.slo[t], w.shi[t]};
    within(_mm512_add_pd(a, _mm512_mul_pd(xq, cq0)), b, m0, s0);
    within(_mm512_add_pd(a, _mm512_mul_pd(xq, cq1)), b, m1, s1);
  }
  maybe16 = _cvtmask16_u32(_mm512_kunpackb(m1, m0)),
  sure16 = _cvtmask16_u32(_mm512_kunpackb(s1, s0));
}

KILN_AVX512 void window_masks_avx512(const WindowJob& job, WindowMasks* out) {
  WindowTests w;
  window_tests(job, w);
  __m512d cen[3][2];
  for (int a = 0; a < 3; ++a)
    for (unsigned k = 0; k < job.windows[a]; ++k)
      cen[a][k] = _mm512_add_pd(_mm512_set1_pd(job.base[a] + 4 * k),
                                _mm512_load_pd(kRotation8[job.s[a] & 3]));
  // The edge masks per axis i and window pair (k_p, k_q), expanded along i.
  WindowMasks edges[3][2][2];
  for (int i = 0; i < 3; ++i) {
    const int p = (i + 1) % 3, q = (i + 2) % 3;
    for (unsigned kp = 0; kp < job.windows[p]; ++kp)
      for (unsigned kq = 0; kq < job.windows[q]; ++kq) {
        __m512d pq[3];
        pq[p] = cen[p][kp], pq[q] = cen[q][kq], pq[i] = cen[i][0];
        unsigned maybe16, sure16;
        edge_masks(w, pq, i, maybe16, sure16);
        edges[i][kp][kq] = {expand_window_mask(i, maybe16), expand_window_mask(i, sure16)};
      }
  }
  for (unsigned kz = 0; kz < job.windows[2]; ++kz)
    for (unsigned ky = 0; ky < job.windows[1]; ++ky)
      for (unsigned kx = 0; kx < job.windows[0]; ++kx) {
        const __m512d c[3] = {cen[0][kx], cen[1][ky], cen[2][kz]};
        WindowMasks m = plane_masks(w, c);
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
