// The portable wide-BVH kernel: the traversal of bvh_wide_traverse.inl over plain float arrays,
// for any CPU and the reference the SIMD kernels are tested against.
#include "bvh_wide_kernel_common.hpp"

namespace kiln::bvh_wide {

namespace {

#define KILN_SIMD inline
#define KILN_SIMD_ENTRY

template <int N>
struct ArrayVec {
  struct T {
    float v[N];
  };
  template <class Op>
  static T map(const T& a, const T& b, Op op) {
    T r;
    for (int i = 0; i < N; ++i) r.v[i] = op(a.v[i], b.v[i]);
    return r;
  }
  template <class Op>
  static unsigned bits(const T& a, const T& b, Op op) {
    unsigned m = 0;
    for (int i = 0; i < N; ++i) m |= unsigned(op(a.v[i], b.v[i])) << i;
    return m;
  }
  static T load(const float* p) {
    T r;
    std::memcpy(r.v, p, sizeof r.v);
    return r;
  }
  static T load_u8(const std::uint8_t* p) {
    T r;
    for (int i = 0; i < N; ++i) r.v[i] = float(p[i]);
    return r;
  }
  static void store(float* p, const T& a) { std::memcpy(p, a.v, sizeof a.v); }
  static T set1(float x) {
    T r;
    for (int i = 0; i < N; ++i) r.v[i] = x;
    return r;
  }
  static T add(T a, T b) {
    return map(a, b, [](float x, float y) { return x + y; });
  }
  static T sub(T a, T b) {
    return map(a, b, [](float x, float y) { return x - y; });
  }
  static T mul(T a, T b) {
    return map(a, b, [](float x, float y) { return x * y; });
  }
  static T div(T a, T b) {
    return map(a, b, [](float x, float y) { return x / y; });
  }
  static T max(T a, T b) {
    return map(a, b, [](float x, float y) { return x > y ? x : y; });
  }
  static T min(T a, T b) {
    return map(a, b, [](float x, float y) { return x < y ? x : y; });
  }
  static unsigned lt(T a, T b) {
    return bits(a, b, [](float x, float y) { return x < y; });
  }
  static unsigned gt(T a, T b) {
    return bits(a, b, [](float x, float y) { return x > y; });
  }
  static unsigned le(T a, T b) {
    return bits(a, b, [](float x, float y) { return x <= y; });
  }
  static unsigned eq(T a, T b) {
    return bits(a, b, [](float x, float y) { return x == y; });
  }
  using M = unsigned;
  static M lt_m(T a, T b) { return lt(a, b); }
  static M gt_m(T a, T b) { return gt(a, b); }
  static M eq_m(T a, T b) { return eq(a, b); }
  static M or_m(M a, M b) { return a | b; }
  static M and_m(M a, M b) { return a & b; }
  static M andnot_m(M a, M b) { return ~a & b; }
  static unsigned bits(M a) { return a & ((1u << N) - 1u); }
};
using F4 = ArrayVec<4>;
using F8 = ArrayVec<8>;

#include "bvh_wide_traverse.inl"

KILN_WIDE_KERNEL_TABLE(scalar)

}  // namespace

const BvhWideKernel* scalar_kernel(std::uint32_t width, bool quantized) {
  if (width == 16) return quantized ? nullptr : &kscalar16;
  return width == 4 || width == 8 ? &kscalar[quantized][width / 8] : nullptr;
}

}  // namespace kiln::bvh_wide
