// Four-lane float vectors on SSE2 registers, for the wide-BVH kernels (see
// bvh_wide_traverse.inl for the contract). Included inside an anonymous namespace after the
// includer defines KILN_SIMD; compiled with VEX encoding in the AVX2 and AVX-512 kernels.
struct SseF4 {
  using T = __m128;
  KILN_SIMD static T load(const float* p) { return _mm_loadu_ps(p); }
  KILN_SIMD static void store(float* p, T a) { _mm_storeu_ps(p, a); }
  // Four bytes to floats with SSE2 alone (zero-extend twice).
  KILN_SIMD static T load_u8(const std::uint8_t* p) {
    std::int32_t word;
    std::memcpy(&word, p, sizeof word);
    const __m128i zero = _mm_setzero_si128();
    const __m128i x = _mm_unpacklo_epi8(_mm_cvtsi32_si128(word), zero);
    return _mm_cvtepi32_ps(_mm_unpacklo_epi16(x, zero));
  }
  KILN_SIMD static T set1(float x) { return _mm_set1_ps(x); }
  KILN_SIMD static T add(T a, T b) { return _mm_add_ps(a, b); }
  KILN_SIMD static T sub(T a, T b) { return _mm_sub_ps(a, b); }
  KILN_SIMD static T mul(T a, T b) { return _mm_mul_ps(a, b); }
  KILN_SIMD static T div(T a, T b) { return _mm_div_ps(a, b); }
  // maxps/minps return the second operand unless the first is strictly greater/less.
  KILN_SIMD static T max(T a, T b) { return _mm_max_ps(a, b); }
  KILN_SIMD static T min(T a, T b) { return _mm_min_ps(a, b); }
  KILN_SIMD static unsigned lt(T a, T b) { return unsigned(_mm_movemask_ps(_mm_cmplt_ps(a, b))); }
  KILN_SIMD static unsigned gt(T a, T b) { return unsigned(_mm_movemask_ps(_mm_cmpgt_ps(a, b))); }
  KILN_SIMD static unsigned le(T a, T b) { return unsigned(_mm_movemask_ps(_mm_cmple_ps(a, b))); }
  KILN_SIMD static unsigned eq(T a, T b) { return unsigned(_mm_movemask_ps(_mm_cmpeq_ps(a, b))); }
  // Lane masks kept in a register, combined there, turned into bits once.
  using M = __m128;
  KILN_SIMD static M lt_m(T a, T b) { return _mm_cmplt_ps(a, b); }
  KILN_SIMD static M gt_m(T a, T b) { return _mm_cmpgt_ps(a, b); }
  KILN_SIMD static M eq_m(T a, T b) { return _mm_cmpeq_ps(a, b); }
  KILN_SIMD static M or_m(M a, M b) { return _mm_or_ps(a, b); }
  KILN_SIMD static M and_m(M a, M b) { return _mm_and_ps(a, b); }
  KILN_SIMD static M andnot_m(M a, M b) { return _mm_andnot_ps(a, b); }  // ~a & b
  KILN_SIMD static unsigned bits(M a) { return unsigned(_mm_movemask_ps(a)); }
};
