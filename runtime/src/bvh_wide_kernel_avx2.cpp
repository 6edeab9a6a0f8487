// The AVX2 wide-BVH kernel: 8-wide nodes in one 256-bit register, triangle packets in VEX-encoded
// 128-bit registers. Only these functions carry the target attribute; the library runs on any
// x86-64 and the kernel is chosen at run time (bvh_wide_view.cpp).
#include "bvh_wide_kernel_common.hpp"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>

namespace kiln::bvh_wide {

namespace {

#define KILN_SIMD __attribute__((target("avx2"), always_inline)) inline
#define KILN_SIMD_ENTRY __attribute__((target("avx2")))

#include "bvh_wide_simd_sse.inl"

struct AvxF8 {
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
  KILN_SIMD static unsigned le(T a, T b) {
    return unsigned(_mm256_movemask_ps(_mm256_cmp_ps(a, b, _CMP_LE_OQ)));
  }
};

using F4 = SseF4;
using F8 = AvxF8;

#include "bvh_wide_traverse.inl"

KILN_WIDE_KERNEL_TABLE(avx2)

}  // namespace

const BvhWideKernel* avx2_kernel(std::uint32_t width, bool quantized) {
  if (width == 16) return quantized ? nullptr : &kavx216;
  return width == 4 || width == 8 ? &kavx2[quantized][width / 8] : nullptr;
}

}  // namespace kiln::bvh_wide

#else

namespace kiln::bvh_wide {
const BvhWideKernel* avx2_kernel(std::uint32_t, bool) {
  return nullptr;
}
}  // namespace kiln::bvh_wide

#endif
