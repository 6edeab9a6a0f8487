// The window kernel (voxelize_window.hpp) with AVX2: four doubles per register, the comparisons
// as all-ones lanes ANDed across the tests and read out with movemask.
#include "voxelize_window.hpp"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>

#define KILN_AVX2 __attribute__((target("avx2,fma")))
#define KILN_AVX2_INLINE __attribute__((target("avx2,fma"), always_inline)) inline

namespace kiln::voxelize_detail {

namespace {

// Lanes 4v + l of a 3D or 2D mask: l's two bits are coordinate bits 0 of the first two axes, so a
// register holds cen[0..1] or cen[2..3] of them in one of two patterns.
KILN_AVX2_INLINE __m256d alternate(__m256d cen, int high) {  // cen[k], cen[k + 1], ... by l & 1
  return high ? _mm256_permute4x64_pd(cen, 0xEE) : _mm256_permute4x64_pd(cen, 0x44);
}
KILN_AVX2_INLINE __m256d pairs(__m256d cen, int high) {  // cen[k], cen[k], cen[k + 1], ...
  return high ? _mm256_permute4x64_pd(cen, 0xFA) : _mm256_permute4x64_pd(cen, 0x50);
}

// acc_m &= lo <= x <= hi, acc_s &= slo <= x <= shi.
KILN_AVX2_INLINE void within(__m256d x, const __m256d* b, __m256d& acc_m, __m256d& acc_s) {
  acc_m = _mm256_and_pd(
      acc_m, _mm256_and_pd(_mm256_cmp_pd(x, b[0], _CMP_GE_OQ), _mm256_cmp_pd(x, b[1], _CMP_LE_OQ)));
  acc_s = _mm256_and_pd(
      acc_s, _mm256_and_pd(_mm256_cmp_pd(x, b[2], _CMP_GE_OQ), _mm256_cmp_pd(x, b[3], _CMP_LE_OQ)));
}

// 3D lanes 4v + l: coord_x = (l & 1) | (v >> 1 & 1) << 1, coord_y = (l >> 1) | (v >> 2 & 1) << 1,
// coord_z = (v & 1) | (v >> 3) << 1.
KILN_AVX2_INLINE WindowMasks plane_masks(const WindowTests& w, const __m256d* cen,
                                         const double* cz) {
  __m256d px[2], py[2], pz[4];
  for (int b = 0; b < 2; ++b)
    px[b] = _mm256_mul_pd(_mm256_set1_pd(w.n[0]), alternate(cen[0], b)),
    py[b] = _mm256_mul_pd(_mm256_set1_pd(w.n[1]), pairs(cen[1], b));
  for (int k = 0; k < 4; ++k) pz[k] = _mm256_mul_pd(_mm256_set1_pd(w.n[2]), _mm256_set1_pd(cz[k]));
  __m256d b[4];
  for (int k = 0; k < 4; ++k) b[k] = _mm256_set1_pd(w.plane[k]);
  WindowMasks out{0, 0};
  const __m256d ones = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
  for (int v = 0; v < 16; ++v) {
    const __m256d x =
        _mm256_add_pd(_mm256_add_pd(px[v >> 1 & 1], py[v >> 2 & 1]), pz[(v & 1) | (v >> 3) << 1]);
    __m256d m = ones, s = ones;
    within(x, b, m, s);
    out.maybe |= std::uint64_t(_mm256_movemask_pd(m)) << (4 * v);
    out.sure |= std::uint64_t(_mm256_movemask_pd(s)) << (4 * v);
  }
  return out;
}

// The three edge tests of axis i on the plane (p, q) = (i + 1, i + 2), 2D lanes 4h + l:
// p = (l & 1) | (h & 1) << 1, q = (l >> 1) | (h >> 1) << 1.
KILN_AVX2_INLINE void edge_masks(const WindowTests& w, const __m256d* cen, int i, unsigned& maybe16,
                                 unsigned& sure16) {
  const __m256d cp[2] = {alternate(cen[(i + 1) % 3], 0), alternate(cen[(i + 1) % 3], 1)};
  const __m256d cq[2] = {pairs(cen[(i + 2) % 3], 0), pairs(cen[(i + 2) % 3], 1)};
  const __m256d ones = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
  __m256d m[4] = {ones, ones, ones, ones}, s[4] = {ones, ones, ones, ones};
  for (int t = 3 * i; t < 3 * i + 3; ++t) {
    const __m256d xp = _mm256_set1_pd(w.xp[t]), xq = _mm256_set1_pd(w.xq[t]);
    const __m256d a[2] = {_mm256_mul_pd(xp, cp[0]), _mm256_mul_pd(xp, cp[1])};
    const __m256d c[2] = {_mm256_mul_pd(xq, cq[0]), _mm256_mul_pd(xq, cq[1])};
    const __m256d b[4] = {_mm256_set1_pd(w.lo[t]), _mm256_set1_pd(w.hi[t]),
                          _mm256_set1_pd(w.slo[t]), _mm256_set1_pd(w.shi[t])};
    for (int h = 0; h < 4; ++h) within(_mm256_add_pd(a[h & 1], c[h >> 1]), b, m[h], s[h]);
  }
  maybe16 = sure16 = 0;
  for (int h = 0; h < 4; ++h)
    maybe16 |= unsigned(_mm256_movemask_pd(m[h])) << (4 * h),
        sure16 |= unsigned(_mm256_movemask_pd(s[h])) << (4 * h);
}

KILN_AVX2 void window_masks_avx2(const WindowJob& job, WindowMasks* out) {
  WindowTests w;
  window_tests(job, w);
  __m256d cen[3][kWindowsPerAxis];
  double cz[kWindowsPerAxis][4];
  for (int a = 0; a < 3; ++a)
    for (unsigned k = 0; k < job.windows[a]; ++k)
      cen[a][k] = _mm256_add_pd(_mm256_set1_pd(job.base[a] + 4 * k),
                                _mm256_loadu_pd(kWindowRotation[job.s[a] & 3]));
  for (unsigned k = 0; k < job.windows[2]; ++k)
    for (int c = 0; c < 4; ++c) cz[k][c] = (job.base[2] + 4 * k) + kWindowRotation[job.s[2] & 3][c];
  // The edge masks per axis i and window pair (k_p, k_q), expanded along i.
  WindowMasks edges[3][kWindowsPerAxis][kWindowsPerAxis];
  for (int i = 0; i < 3; ++i) {
    const int p = (i + 1) % 3, q = (i + 2) % 3;
    for (unsigned kp = 0; kp < job.windows[p]; ++kp)
      for (unsigned kq = 0; kq < job.windows[q]; ++kq) {
        __m256d pq[3];
        pq[p] = cen[p][kp], pq[q] = cen[q][kq], pq[i] = cen[i][0];
        unsigned maybe16, sure16;
        edge_masks(w, pq, i, maybe16, sure16);
        edges[i][kp][kq] = {expand_window_mask(i, maybe16), expand_window_mask(i, sure16)};
      }
  }
  for (unsigned kz = 0; kz < job.windows[2]; ++kz)
    for (unsigned ky = 0; ky < job.windows[1]; ++ky)
      for (unsigned kx = 0; kx < job.windows[0]; ++kx) {
        const __m256d c[3] = {cen[0][kx], cen[1][ky], cen[2][kz]};
        WindowMasks m = plane_masks(w, c, cz[kz]);
        const WindowMasks* e[3] = {&edges[0][ky][kz], &edges[1][kz][kx], &edges[2][kx][ky]};
        for (const WindowMasks* x : e) m.maybe &= x->maybe, m.sure &= x->sure;
        out[kx + kWindowsPerAxis * (ky + kWindowsPerAxis * kz)] = m;
      }
}

}  // namespace

WindowKernel window_kernel_avx2() {
  return window_masks_avx2;
}

}  // namespace kiln::voxelize_detail

#else

namespace kiln::voxelize_detail {
WindowKernel window_kernel_avx2() {
  return nullptr;
}
}  // namespace kiln::voxelize_detail

#endif
