// The window kernel (voxelize_window.hpp) with AVX2 in single precision: eight floats per register
// (a 4x4x4 window's plane test in eight registers, an edge test's 4x4 plane in two), comparisons
// ANDed across the tests and read out with movemask. The tests are set up in scalar double
// (window_tests) and widened by the float evaluation's error (window_float_bounds), so the
// decisions stay the predicate's.
#include "voxelize_window.hpp"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>

#define KILN_AVX2 __attribute__((target("avx2,fma")))
#define KILN_AVX2_INLINE __attribute__((target("avx2,fma"), always_inline)) inline

namespace kiln::voxelize_detail {

namespace {

// Index patterns over 8 lanes. 3D lanes 8v + l: l's bits are x0, y0, z0 and v's x1, y1, z1, so
// each axis a has two patterns (by v's bit a). 2D lanes 8h + l: l's bits p0, q0, p1, h = q1.
alignas(32) constexpr int kPattern3[3][2][8] = {
    {{0, 1, 0, 1, 0, 1, 0, 1}, {2, 3, 2, 3, 2, 3, 2, 3}},
    {{0, 0, 1, 1, 0, 0, 1, 1}, {2, 2, 3, 3, 2, 2, 3, 3}},
    {{0, 0, 0, 0, 1, 1, 1, 1}, {2, 2, 2, 2, 3, 3, 3, 3}}};
alignas(32) constexpr int kPatternP[8] = {0, 1, 0, 1, 2, 3, 2, 3};
alignas(32) constexpr int kPatternQ[2][8] = {{0, 0, 1, 1, 0, 0, 1, 1}, {2, 2, 3, 3, 2, 2, 3, 3}};
alignas(32) constexpr float kRotation8[4][8] = {
    {0, 1, 2, 3}, {3, 0, 1, 2}, {2, 3, 0, 1}, {1, 2, 3, 0}};

KILN_AVX2_INLINE __m256 spread(__m256 cen, const int (&index)[8]) {
  return _mm256_permutevar8x32_ps(cen, _mm256_load_si256(reinterpret_cast<const __m256i*>(index)));
}

// The float form of the tests: axes rounded to float, bounds from window_float_bounds.
struct FloatTests {
  float n[3], plane[4];
  float xp[9], xq[9], b[9][4];
};

KILN_AVX2_INLINE void float_tests(const WindowJob& job, FloatTests& f) {
  WindowTests w;
  window_tests(job, w);
  for (int a = 0; a < 3; ++a) f.n[a] = float(w.n[a]);
  window_float_bounds(w.plane_slab[0], w.plane_slab[1], w.plane_m, w.plane_r, job.extent, f.plane);
  for (int t = 0; t < 9; ++t) {
    f.xp[t] = float(w.xp[t]), f.xq[t] = float(w.xq[t]);
    window_float_bounds(w.slab_lo[t], w.slab_hi[t], w.edge_m, w.r[t], job.extent, f.b[t]);
  }
}

// The lanes of x within b[0..1] (maybe) and b[2..3] (sure), as all-ones lanes.
KILN_AVX2_INLINE void within(__m256 x, const float* b, __m256& maybe, __m256& sure) {
  maybe = _mm256_and_ps(maybe, _mm256_and_ps(_mm256_cmp_ps(x, _mm256_set1_ps(b[0]), _CMP_GE_OQ),
                                             _mm256_cmp_ps(x, _mm256_set1_ps(b[1]), _CMP_LE_OQ)));
  sure = _mm256_and_ps(sure, _mm256_and_ps(_mm256_cmp_ps(x, _mm256_set1_ps(b[2]), _CMP_GE_OQ),
                                           _mm256_cmp_ps(x, _mm256_set1_ps(b[3]), _CMP_LE_OQ)));
}

KILN_AVX2_INLINE WindowMasks plane_masks(const FloatTests& f, const __m256* cen) {
  __m256 part[3][2];
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 2; ++b)
      part[a][b] = _mm256_mul_ps(_mm256_set1_ps(f.n[a]), spread(cen[a], kPattern3[a][b]));
  const __m256 ones = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
  WindowMasks out{0, 0};
  for (int v = 0; v < 8; ++v) {
    const __m256 x =
        _mm256_add_ps(_mm256_add_ps(part[0][v & 1], part[1][v >> 1 & 1]), part[2][v >> 2 & 1]);
    __m256 maybe = ones, sure = ones;
    within(x, f.plane, maybe, sure);
    out.maybe |= std::uint64_t(unsigned(_mm256_movemask_ps(maybe))) << (8 * v);
    out.sure |= std::uint64_t(unsigned(_mm256_movemask_ps(sure))) << (8 * v);
  }
  return out;
}

// The 16 lanes of two registers as bits.
KILN_AVX2_INLINE unsigned bits16(const __m256* m) {
  return unsigned(_mm256_movemask_ps(m[0])) | unsigned(_mm256_movemask_ps(m[1])) << 8;
}

// The three edge tests of axis i on the window pair's plane (i + 1, i + 2), expanded along i.
KILN_AVX2_INLINE WindowMasks edge_masks(const FloatTests& f, __m256 cen_p, __m256 cen_q, int i) {
  const __m256 cp = spread(cen_p, kPatternP);
  const __m256 cq[2] = {spread(cen_q, kPatternQ[0]), spread(cen_q, kPatternQ[1])};
  const __m256 ones = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
  __m256 maybe[2] = {ones, ones}, sure[2] = {ones, ones};
  for (int t = 3 * i; t < 3 * i + 3; ++t) {
    const __m256 a = _mm256_mul_ps(_mm256_set1_ps(f.xp[t]), cp), xq = _mm256_set1_ps(f.xq[t]);
    for (int h = 0; h < 2; ++h)
      within(_mm256_add_ps(a, _mm256_mul_ps(xq, cq[h])), f.b[t], maybe[h], sure[h]);
  }
  return {expand_window_mask(i, bits16(maybe)), expand_window_mask(i, bits16(sure))};
}

// The voxels (lanes) of the window whose first voxel has local centre coordinate `base`, with
// s = g & 3 (voxelize_window.hpp: lane order).
KILN_AVX2_INLINE __m256 window_centres(float base, unsigned s) {
  return _mm256_add_ps(_mm256_set1_ps(base), _mm256_load_ps(kRotation8[s & 3]));
}

#define KILN_WINDOW_ENTRY KILN_AVX2
#include "voxelize_window_driver.inl"
#undef KILN_WINDOW_ENTRY

}  // namespace

WindowKernel window_kernel_avx2() {
  return window_masks<__m256>;
}

}  // namespace kiln::voxelize_detail

#else

namespace kiln::voxelize_detail {
WindowKernel window_kernel_avx2() {
  return nullptr;
}
}  // namespace kiln::voxelize_detail

#endif
