// The AVX-512 wide-BVH kernel (AVX-512F + VL): the AVX2 kernel's registers, with compares that
// write mask registers directly (no movemask) and the compiler free to use the EVEX forms.
#include "bvh_wide_kernel_common.hpp"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>

#if defined(__GNUC__) && !defined(__clang__)
// GCC 12's _mm512_max_ps/_mm512_min_ps pass _mm512_undefined_ps() to a masked builtin, which
// -Wmaybe-uninitialized reports once inlined here (a false positive: the mask is all ones).
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

namespace kiln::bvh_wide {

namespace {

#define KILN_SIMD __attribute__((target("avx2,avx512f,avx512vl"), always_inline)) inline
#define KILN_SIMD_ENTRY __attribute__((target("avx2,avx512f,avx512vl")))

struct Avx512F4 {
  using T = __m128;
  KILN_SIMD static T load(const float* p) { return _mm_loadu_ps(p); }
  KILN_SIMD static void store(float* p, T a) { _mm_storeu_ps(p, a); }
  KILN_SIMD static T load_u8(const std::uint8_t* p) {
    std::int32_t word;
    std::memcpy(&word, p, sizeof word);
    return _mm_cvtepi32_ps(_mm_cvtepu8_epi32(_mm_cvtsi32_si128(word)));
  }
  KILN_SIMD static T set1(float x) { return _mm_set1_ps(x); }
  KILN_SIMD static T add(T a, T b) { return _mm_add_ps(a, b); }
  KILN_SIMD static T sub(T a, T b) { return _mm_sub_ps(a, b); }
  KILN_SIMD static T mul(T a, T b) { return _mm_mul_ps(a, b); }
  KILN_SIMD static T div(T a, T b) { return _mm_div_ps(a, b); }
  KILN_SIMD static T max(T a, T b) { return _mm_max_ps(a, b); }
  KILN_SIMD static T min(T a, T b) { return _mm_min_ps(a, b); }
  KILN_SIMD static unsigned lt(T a, T b) { return _mm_cmp_ps_mask(a, b, _CMP_LT_OQ); }
  KILN_SIMD static unsigned gt(T a, T b) { return _mm_cmp_ps_mask(a, b, _CMP_GT_OQ); }
  KILN_SIMD static unsigned le(T a, T b) { return _mm_cmp_ps_mask(a, b, _CMP_LE_OQ); }
  KILN_SIMD static unsigned eq(T a, T b) { return _mm_cmp_ps_mask(a, b, _CMP_EQ_OQ); }
  using M = unsigned;  // mask registers already
  KILN_SIMD static M lt_m(T a, T b) { return lt(a, b); }
  KILN_SIMD static M gt_m(T a, T b) { return gt(a, b); }
  KILN_SIMD static M eq_m(T a, T b) { return eq(a, b); }
  KILN_SIMD static M or_m(M a, M b) { return a | b; }
  KILN_SIMD static M and_m(M a, M b) { return a & b; }
  KILN_SIMD static M andnot_m(M a, M b) { return ~a & b; }
  KILN_SIMD static unsigned bits(M a) { return a & 0xFu; }
};

struct Avx512F8 {
  using T = __m256;
  KILN_SIMD static T load(const float* p) { return _mm256_loadu_ps(p); }
  KILN_SIMD static T load_u8(const std::uint8_t* p) {
    const __m128i bytes = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(p));
    return _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(bytes));
  }
  KILN_SIMD static T add(T a, T b) { return _mm256_add_ps(a, b); }
  KILN_SIMD static void store(float* p, T a) { _mm256_storeu_ps(p, a); }
  KILN_SIMD static T set1(float x) { return _mm256_set1_ps(x); }
  KILN_SIMD static T sub(T a, T b) { return _mm256_sub_ps(a, b); }
  KILN_SIMD static T mul(T a, T b) { return _mm256_mul_ps(a, b); }
  KILN_SIMD static T max(T a, T b) { return _mm256_max_ps(a, b); }
  KILN_SIMD static T min(T a, T b) { return _mm256_min_ps(a, b); }
  KILN_SIMD static unsigned le(T a, T b) { return _mm256_cmp_ps_mask(a, b, _CMP_LE_OQ); }
};

// 16-wide nodes (float boxes only): one 512-bit register per plane.
struct Avx512F16 {
  using T = __m512;
  KILN_SIMD static T load(const float* p) { return _mm512_loadu_ps(p); }
  KILN_SIMD static T add(T a, T b) { return _mm512_add_ps(a, b); }
  KILN_SIMD static void store(float* p, T a) { _mm512_storeu_ps(p, a); }
  KILN_SIMD static T set1(float x) { return _mm512_set1_ps(x); }
  KILN_SIMD static T sub(T a, T b) { return _mm512_sub_ps(a, b); }
  KILN_SIMD static T mul(T a, T b) { return _mm512_mul_ps(a, b); }
  KILN_SIMD static T max(T a, T b) { return _mm512_max_ps(a, b); }
  KILN_SIMD static T min(T a, T b) { return _mm512_min_ps(a, b); }
  KILN_SIMD static unsigned le(T a, T b) { return _mm512_cmp_ps_mask(a, b, _CMP_LE_OQ); }
};

using F4 = Avx512F4;
using F8 = Avx512F8;
#define KILN_WIDE_F16 Avx512F16
#define KILN_WIDE_RANKS_AVX512

#include "bvh_wide_traverse.inl"

KILN_WIDE_KERNEL_TABLE(avx512)

}  // namespace

const BvhWideKernel* avx512_kernel(std::uint32_t width, bool quantized) {
  if (width == 16) return quantized ? nullptr : &kavx51216;
  return width == 4 || width == 8 ? &kavx512[quantized][width / 8] : nullptr;
}

}  // namespace kiln::bvh_wide

#else

namespace kiln::bvh_wide {
const BvhWideKernel* avx512_kernel(std::uint32_t, bool) {
  return nullptr;
}
}  // namespace kiln::bvh_wide

#endif
