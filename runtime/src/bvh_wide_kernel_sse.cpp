// The SSE2 wide-BVH kernel (every x86-64 CPU has SSE2): 4-wide nodes in one register, 8-wide
// nodes in two.
#include "bvh_wide_kernel_common.hpp"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>

namespace kiln::bvh_wide {

namespace {

#define KILN_SIMD __attribute__((always_inline)) inline
#define KILN_SIMD_ENTRY

#include "bvh_wide_simd_sse.inl"

// Eight lanes as two SSE halves.
struct SseF8 {
  struct T {
    __m128 lo, hi;
  };
  KILN_SIMD static T load(const float* p) { return {_mm_loadu_ps(p), _mm_loadu_ps(p + 4)}; }
  KILN_SIMD static void store(float* p, T a) { _mm_storeu_ps(p, a.lo), _mm_storeu_ps(p + 4, a.hi); }
  KILN_SIMD static T set1(float x) { return {_mm_set1_ps(x), _mm_set1_ps(x)}; }
  KILN_SIMD static T load_u8(const std::uint8_t* p) {
    const __m128i zero = _mm_setzero_si128();
    const __m128i x = _mm_unpacklo_epi8(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(p)), zero);
    return {_mm_cvtepi32_ps(_mm_unpacklo_epi16(x, zero)),
            _mm_cvtepi32_ps(_mm_unpackhi_epi16(x, zero))};
  }
  KILN_SIMD static T add(T a, T b) { return {_mm_add_ps(a.lo, b.lo), _mm_add_ps(a.hi, b.hi)}; }
  KILN_SIMD static T sub(T a, T b) { return {_mm_sub_ps(a.lo, b.lo), _mm_sub_ps(a.hi, b.hi)}; }
  KILN_SIMD static T mul(T a, T b) { return {_mm_mul_ps(a.lo, b.lo), _mm_mul_ps(a.hi, b.hi)}; }
  KILN_SIMD static T max(T a, T b) { return {_mm_max_ps(a.lo, b.lo), _mm_max_ps(a.hi, b.hi)}; }
  KILN_SIMD static T min(T a, T b) { return {_mm_min_ps(a.lo, b.lo), _mm_min_ps(a.hi, b.hi)}; }
  KILN_SIMD static unsigned le(T a, T b) {
    return unsigned(_mm_movemask_ps(_mm_cmple_ps(a.lo, b.lo)) |
                    _mm_movemask_ps(_mm_cmple_ps(a.hi, b.hi)) << 4);
  }
};

using F4 = SseF4;
using F8 = SseF8;

#include "bvh_wide_traverse.inl"

KILN_WIDE_KERNEL_TABLE(sse)

}  // namespace

const BvhWideKernel* sse_kernel(std::uint32_t width, bool quantized) {
  if (width == 16) return quantized ? nullptr : &ksse16;
  return width == 4 || width == 8 ? &ksse[quantized][width / 8] : nullptr;
}

}  // namespace kiln::bvh_wide

#else

namespace kiln::bvh_wide {
const BvhWideKernel* sse_kernel(std::uint32_t, bool) {
  return nullptr;
}
}  // namespace kiln::bvh_wide

#endif
