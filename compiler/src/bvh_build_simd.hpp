// Four-float vectors for the BVH builders: SSE2 (the x86-64 baseline, no dispatch needed) or a
// portable fallback with the same results. min/max keep the operand order of Box3f::grow
// (`vmin(x, acc)` is `x < acc ? x : acc`, as std::min(acc, x)), so a box grown here is the same,
// bit for bit and signed zeros included, as one grown with Box3f in the same order.
#pragma once

#include <bit>
#include <cstdint>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include "huge_pages.hpp"
#include "kiln/formats/vector.hpp"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace kiln::bvh_simd {

#if defined(__SSE2__)
struct V4 {
  __m128 v;
};
inline V4 load(const float* p) {
  return {_mm_load_ps(p)};
}
inline void store(float* p, V4 a) {
  _mm_store_ps(p, a.v);
}
inline V4 splat(float x) {
  return {_mm_set1_ps(x)};
}
inline V4 set(float x, float y, float z, float w) {
  return {_mm_setr_ps(x, y, z, w)};
}
inline V4 operator+(V4 a, V4 b) {
  return {_mm_add_ps(a.v, b.v)};
}
inline V4 operator-(V4 a, V4 b) {
  return {_mm_sub_ps(a.v, b.v)};
}
inline V4 operator*(V4 a, V4 b) {
  return {_mm_mul_ps(a.v, b.v)};
}
inline V4 vmin(V4 x, V4 acc) {
  return {_mm_min_ps(x.v, acc.v)};
}  // x < acc ? x : acc
inline V4 vmax(V4 x, V4 acc) {
  return {_mm_max_ps(x.v, acc.v)};
}  // x > acc ? x : acc
// Lanes 0-2 of `a`, lane 3 zero.
inline V4 xyz(V4 a) {
  return {_mm_and_ps(a.v, _mm_castsi128_ps(_mm_setr_epi32(-1, -1, -1, 0)))};
}
// `take` ? a : b, lane-wise by a whole-vector condition, without a branch.
inline V4 select(bool take, V4 a, V4 b) {
  const __m128 m = _mm_castsi128_ps(_mm_set1_epi32(-std::int32_t(take)));
  return {_mm_or_ps(_mm_and_ps(m, a.v), _mm_andnot_ps(m, b.v))};
}
// Truncating conversion of lanes already clamped to [0, 2^31).
inline void truncate(V4 a, std::int32_t* out) {
  _mm_store_si128(reinterpret_cast<__m128i*>(out), _mm_cvttps_epi32(a.v));
}
// Bit i set where lane i of a < lane i of b.
inline int less_mask(V4 a, V4 b) {
  return _mm_movemask_ps(_mm_cmplt_ps(a.v, b.v));
}
inline V4 operator/(V4 a, V4 b) {
  return {_mm_div_ps(a.v, b.v)};
}
// Lane-wise masks (all bits set where true), as V4.
inline V4 lt(V4 a, V4 b) {
  return {_mm_cmplt_ps(a.v, b.v)};
}
inline V4 le(V4 a, V4 b) {
  return {_mm_cmple_ps(a.v, b.v)};
}
inline V4 operator&(V4 a, V4 b) {
  return {_mm_and_ps(a.v, b.v)};
}
inline V4 operator|(V4 a, V4 b) {
  return {_mm_or_ps(a.v, b.v)};
}
// Lane-wise m ? a : b for a mask m.
inline V4 blend(V4 m, V4 a, V4 b) {
  return {_mm_or_ps(_mm_and_ps(m.v, a.v), _mm_andnot_ps(m.v, b.v))};
}
// Bit i set where mask lane i is set.
inline int mask_bits(V4 m) {
  return _mm_movemask_ps(m.v);
}
// Lane 3 as an unsigned integer (its bits), and lane 3 plus `n` as integers (lanes 0-2 kept).
inline std::uint32_t lane3_bits(V4 a) {
  return std::uint32_t(_mm_cvtsi128_si32(_mm_castps_si128(_mm_shuffle_ps(a.v, a.v, 0xff))));
}
inline V4 add_lane3(V4 a, std::uint32_t n) {
  return {_mm_castsi128_ps(_mm_add_epi32(_mm_castps_si128(a.v), _mm_setr_epi32(0, 0, 0, int(n))))};
}
// Lanes 0-2 vmax(x, acc), lane 3 the sum of x's and acc's as integers.
inline V4 vmax_add_lane3(V4 x, V4 acc) {
  const __m128i sum = _mm_add_epi32(_mm_castps_si128(x.v), _mm_castps_si128(acc.v));
  const __m128i max = _mm_castps_si128(_mm_max_ps(x.v, acc.v));
  return {_mm_castsi128_ps(_mm_or_si128(_mm_and_si128(max, _mm_setr_epi32(-1, -1, -1, 0)),
                                        _mm_and_si128(sum, _mm_setr_epi32(0, 0, 0, -1))))};
}
// Lanes as 32-bit integers: splat, add, subtract, convert to float (exact below 2^24, rounded
// to nearest above, as a conversion from any integer type), and {a[3], b[3], c[3], 0}.
inline V4 splat_bits(std::uint32_t x) {
  return {_mm_castsi128_ps(_mm_set1_epi32(int(x)))};
}
inline V4 add_bits(V4 a, V4 b) {
  return {_mm_castsi128_ps(_mm_add_epi32(_mm_castps_si128(a.v), _mm_castps_si128(b.v)))};
}
inline V4 sub_bits(V4 a, V4 b) {
  return {_mm_castsi128_ps(_mm_sub_epi32(_mm_castps_si128(a.v), _mm_castps_si128(b.v)))};
}
inline V4 bits_to_float(V4 a) {
  return {_mm_cvtepi32_ps(_mm_castps_si128(a.v))};
}
inline V4 lanes3(V4 a, V4 b, V4 c) {
  return {_mm_movehl_ps(_mm_unpackhi_ps(c.v, _mm_setzero_ps()), _mm_unpackhi_ps(a.v, b.v))};
}
// {prev[3], cur[0], cur[1], cur[2]}: the lanes moved up by one, the first from `prev`.
inline V4 shift_in(V4 prev, V4 cur) {
  const __m128 t = _mm_shuffle_ps(prev.v, cur.v, _MM_SHUFFLE(0, 0, 3, 3));  // p3 p3 c0 c0
  return {_mm_shuffle_ps(t, cur.v, _MM_SHUFFLE(2, 1, 2, 0))};
}
inline V4 loadu(const float* p) {
  return {_mm_loadu_ps(p)};
}
inline void storeu(float* p, V4 a) {
  _mm_storeu_ps(p, a.v);
}
#else
struct V4 {
  float f[4];
};
inline V4 load(const float* p) {
  return {{p[0], p[1], p[2], p[3]}};
}
inline void store(float* p, V4 a) {
  for (int i = 0; i < 4; ++i) p[i] = a.f[i];
}
inline V4 splat(float x) {
  return {{x, x, x, x}};
}
inline V4 set(float x, float y, float z, float w) {
  return {{x, y, z, w}};
}
#define KILN_V4_OP(op)                                                                 \
  inline V4 operator op(V4 a, V4 b) {                                                  \
    return {{a.f[0] op b.f[0], a.f[1] op b.f[1], a.f[2] op b.f[2], a.f[3] op b.f[3]}}; \
  }
KILN_V4_OP(+)
KILN_V4_OP(-)
KILN_V4_OP(*)
KILN_V4_OP(/)
#undef KILN_V4_OP
inline V4 vmin(V4 x, V4 acc) {
  V4 r;
  for (int i = 0; i < 4; ++i) r.f[i] = x.f[i] < acc.f[i] ? x.f[i] : acc.f[i];
  return r;
}
inline V4 vmax(V4 x, V4 acc) {
  V4 r;
  for (int i = 0; i < 4; ++i) r.f[i] = x.f[i] > acc.f[i] ? x.f[i] : acc.f[i];
  return r;
}
inline void truncate(V4 a, std::int32_t* out) {
  for (int i = 0; i < 4; ++i) out[i] = std::int32_t(a.f[i]);
}
inline V4 xyz(V4 a) {
  return {{a.f[0], a.f[1], a.f[2], 0.0f}};
}
inline V4 select(bool take, V4 a, V4 b) {
  return take ? a : b;
}
inline int less_mask(V4 a, V4 b) {
  int m = 0;
  for (int i = 0; i < 4; ++i) m |= int(a.f[i] < b.f[i]) << i;
  return m;
}
inline V4 mask_of(bool t0, bool t1, bool t2, bool t3) {
  const auto f = [](bool t) { return std::bit_cast<float>(t ? ~0u : 0u); };
  return {{f(t0), f(t1), f(t2), f(t3)}};
}
inline V4 lt(V4 a, V4 b) {
  return mask_of(a.f[0] < b.f[0], a.f[1] < b.f[1], a.f[2] < b.f[2], a.f[3] < b.f[3]);
}
inline V4 le(V4 a, V4 b) {
  return mask_of(a.f[0] <= b.f[0], a.f[1] <= b.f[1], a.f[2] <= b.f[2], a.f[3] <= b.f[3]);
}
#define KILN_V4_BITS(op)                                                          \
  inline V4 operator op(V4 a, V4 b) {                                             \
    V4 r;                                                                         \
    for (int i = 0; i < 4; ++i)                                                   \
      r.f[i] = std::bit_cast<float>(std::bit_cast<std::uint32_t>(a.f[i])          \
                                        op std::bit_cast<std::uint32_t>(b.f[i])); \
    return r;                                                                     \
  }
KILN_V4_BITS(&)
KILN_V4_BITS(|)
#undef KILN_V4_BITS
inline int mask_bits(V4 m) {
  int bits = 0;
  for (int i = 0; i < 4; ++i) bits |= int(std::bit_cast<std::uint32_t>(m.f[i]) >> 31) << i;
  return bits;
}
inline V4 blend(V4 m, V4 a, V4 b) {
  V4 r;
  for (int i = 0; i < 4; ++i) r.f[i] = std::bit_cast<std::uint32_t>(m.f[i]) ? a.f[i] : b.f[i];
  return r;
}
inline V4 shift_in(V4 prev, V4 cur) {
  return {{prev.f[3], cur.f[0], cur.f[1], cur.f[2]}};
}
inline std::uint32_t lane3_bits(V4 a) {
  return std::bit_cast<std::uint32_t>(a.f[3]);
}
inline V4 add_lane3(V4 a, std::uint32_t n) {
  a.f[3] = std::bit_cast<float>(lane3_bits(a) + n);
  return a;
}
inline V4 splat_bits(std::uint32_t x) {
  const float f = std::bit_cast<float>(x);
  return {{f, f, f, f}};
}
inline V4 add_bits(V4 a, V4 b) {
  V4 r;
  for (int i = 0; i < 4; ++i)
    r.f[i] = std::bit_cast<float>(std::bit_cast<std::uint32_t>(a.f[i]) +
                                  std::bit_cast<std::uint32_t>(b.f[i]));
  return r;
}
inline V4 sub_bits(V4 a, V4 b) {
  V4 r;
  for (int i = 0; i < 4; ++i)
    r.f[i] = std::bit_cast<float>(std::bit_cast<std::uint32_t>(a.f[i]) -
                                  std::bit_cast<std::uint32_t>(b.f[i]));
  return r;
}
inline V4 bits_to_float(V4 a) {
  V4 r;
  for (int i = 0; i < 4; ++i) r.f[i] = float(std::bit_cast<std::int32_t>(a.f[i]));
  return r;
}
inline V4 lanes3(V4 a, V4 b, V4 c) {
  return {{a.f[3], b.f[3], c.f[3], 0.0f}};
}
inline V4 vmax_add_lane3(V4 x, V4 acc) {
  V4 r = vmax(x, acc);
  r.f[3] = std::bit_cast<float>(lane3_bits(x) + lane3_bits(acc));
  return r;
}
inline V4 loadu(const float* p) {
  return load(p);
}
inline void storeu(float* p, V4 a) {
  store(p, a);
}
#endif

/// A build reference in 32 bytes, two aligned vectors: the box's corners, the primitive id in
/// the lower corner's fourth lane (never used as a float: the upper corner's fourth lane is 0
/// and the centroid takes only the first three lanes into account).
struct alignas(16) BuildRef {
  float lo[4], hi[4];
  std::uint32_t prim() const { return std::bit_cast<std::uint32_t>(lo[3]); }
  format::Box3f box() const { return {{lo[0], lo[1], lo[2]}, {hi[0], hi[1], hi[2]}}; }
  static BuildRef make(const format::Box3f& b, std::uint32_t prim) {
    return {{b.min.x, b.min.y, b.min.z, std::bit_cast<float>(prim)},
            {b.max.x, b.max.y, b.max.z, 0.0f}};
  }
};
static_assert(sizeof(BuildRef) == 32);

/// Build references, allocated without zeroing.
using BuildRefs = UninitializedVector<BuildRef>;  // a parallel fill, no serial zeroing first

/// A box as two vectors (fourth lanes ignored); empty as Box3f's default.
struct VBox {
  V4 lo = splat(std::numeric_limits<float>::infinity());
  V4 hi = splat(-std::numeric_limits<float>::infinity());
  void grow(V4 l, V4 h) { lo = vmin(l, lo), hi = vmax(h, hi); }
  void grow(const VBox& b) { grow(b.lo, b.hi); }
  format::Box3f box() const {
    alignas(16) float l[4], h[4];
    store(l, lo), store(h, hi);
    return {{l[0], l[1], l[2]}, {h[0], h[1], h[2]}};
  }
};

/// Half the surface area of `b`, exactly Box3f::half_area (0 when empty; the same products,
/// summed in the same order). The fourth lanes must be finite (the builders keep them 0).
inline float half_area(const VBox& b) {
#if defined(__SSE2__)
  if (_mm_movemask_ps(_mm_cmplt_ps(b.hi.v, b.lo.v)) & 7) return 0.0f;
  const __m128 d = _mm_sub_ps(b.hi.v, b.lo.v);
  const __m128 p = _mm_mul_ps(d, _mm_shuffle_ps(d, d, _MM_SHUFFLE(3, 0, 2, 1)));  // xy yz zx
  alignas(16) float q[4];
  _mm_store_ps(q, p);
  return q[0] + q[1] + q[2];
#else
  return b.box().half_area();
#endif
}

/// The half areas of three non-empty boxes, one a lane (lane 3 zero): half_area's products
/// summed in its order, so the same floats. (An empty box gives no 0 here, unlike half_area.)
inline V4 half_areas(const VBox& a, const VBox& b, const VBox& c) {
#if defined(__SSE2__)
  __m128 x = _mm_sub_ps(a.hi.v, a.lo.v), y = _mm_sub_ps(b.hi.v, b.lo.v);
  __m128 z = _mm_sub_ps(c.hi.v, c.lo.v), w = _mm_setzero_ps();
  _MM_TRANSPOSE4_PS(x, y, z, w);  // x: the three boxes' extents on x, y on y, z on z
  return {_mm_add_ps(_mm_add_ps(_mm_mul_ps(x, y), _mm_mul_ps(y, z)), _mm_mul_ps(z, x))};
#else
  return set(half_area(a), half_area(b), half_area(c), 0.0f);
#endif
}

/// The lower corner of a reference with the id's lane cleared.
inline V4 lower(const BuildRef& r) {
  return xyz(load(r.lo));
}
inline V4 upper(const BuildRef& r) {
  return load(r.hi);
}

/// The centroid, 0.5 * (lo + hi): lanes 0-2 exactly Box3f::centroid; lane 3 zero (the id bits
/// are masked off first: as a float they are a denormal, slow in arithmetic).
inline V4 centroid(const BuildRef& r) {
  return (xyz(load(r.lo)) + load(r.hi)) * splat(0.5f);
}

}  // namespace kiln::bvh_simd
