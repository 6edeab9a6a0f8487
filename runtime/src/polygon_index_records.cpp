// The leaf records' answer for a point: per group, the centre's mask flipped by the masks of
// the edges that the shifted segment from the centre c to p crosses; the lowest polygon left set
// answers. Each edge is stored oriented so that c lies to its left under the shifted rule, so
// the segment crosses it exactly when a and b lie on opposite sides of line c-p and p lies to
// its right (detail::shifted_segment_crosses_unboxed, whose answer does not depend on the edge's
// direction). A block's twelve orientations go through orient2d's floating-point filter
// without a branch on their signs; a block the filter cannot certify takes the exact test edge
// by edge. Kernels: scalar (any build), SSE2 (two lanes), AVX2 (four lanes, run-time choice).
#include "polygon_index_records.hpp"

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <string_view>

#include "kiln/runtime/capabilities.hpp"
#include "predicates2_inline.hpp"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define KILN_POLYGON_X86 1
#endif

namespace kiln::polygon_records {

using format::Double2;

namespace {

template <class T>
inline T load(const std::uint64_t* words, std::size_t index) {
  T v;
  std::memcpy(&v, reinterpret_cast<const unsigned char*>(words) + index * sizeof(T), sizeof v);
  return v;
}

// One group's head: its blocks, centre mask (bit 31: another group follows), centre, and the
// side of line c-p a vertex on that line counts as (side_of_shifted_line's tie: positive when p
// lies above c, or level with it and to its left; p == c flips nothing, p then being on the
// centre's side of every edge).
struct Group {
  std::uint32_t blocks, head;
  Double2 c;
  bool tie;
};

inline Group group_at(const std::uint64_t* w, const Double2& p) {
  Group g{std::uint32_t(w[0]),
          std::uint32_t(w[0] >> 32),
          {load<double>(w, 1), load<double>(w, 2)},
          false};
  g.tie = (p.y > g.c.y) | ((p.y == g.c.y) & (p.x < g.c.x));
  return g;
}

// After a group's blocks: its polygon count, then its features. The answer for `mask`, or
// kNone with `next` set to the following group (when the head says there is one).
inline bool group_answer(const Group& g, std::uint32_t mask, const std::uint64_t* after,
                         std::uint32_t& answer, const std::uint64_t*& next) {
  if (mask) {
    answer = load<std::uint32_t>(after, 1 + std::uint32_t(__builtin_ctz(mask)));
    return true;
  }
  answer = PolygonQueries::kNone;
  if (!(g.head >> 31)) return true;
  next = after + (2 + load<std::uint32_t>(after, 0)) / 2;
  return false;
}

inline Double2 lane_a(const std::uint64_t* block, int l) {
  return {load<double>(block, l), load<double>(block, 4 + l)};
}
inline Double2 lane_b(const std::uint64_t* block, int l) {
  return {load<double>(block, 8 + l), load<double>(block, 12 + l)};
}

// The exact test, for blocks the filter leaves undecided.
inline std::uint32_t exact_flips(const std::uint64_t* block, const Double2& c, const Double2& p) {
  std::uint32_t flips = 0;
  for (int l = 0; l < 4; ++l)
    if (detail::shifted_segment_crosses_unboxed(c, p, lane_a(block, l), lane_b(block, l)))
      flips ^= load<std::uint32_t>(block + 16, l);
  return flips & 0x7FFFFFFFu;
}

// orient2d(a, b, c) through the filter only: `sure` is cleared when the filter cannot certify
// the sign (detail::orient2d_inline's certificate: opposite-sign or zero terms, or |det| >= the
// error bound; NaN never certified).
inline double orient_filtered(const Double2& a, const Double2& b, const Double2& c, bool& sure) {
  const double dl = (a.x - c.x) * (b.y - c.y), dr = (a.y - c.y) * (b.x - c.x);
  const double det = dl - dr;
  sure &= std::fabs(det) >= detail::kCcwErrBoundA * (std::fabs(dl) + std::fabs(dr));
  return det;
}

inline std::uint32_t scalar_flips(const std::uint64_t* block, const Double2& c, const Double2& p,
                                  bool tie) {
  std::uint32_t flips = 0;
  bool sure = true;
  for (int l = 0; l < 4; ++l) {
    const Double2 a = lane_a(block, l), b = lane_b(block, l);
    const std::uint32_t m = load<std::uint32_t>(block + 16, l);
    const double oa = orient_filtered(c, p, a, sure), ob = orient_filtered(c, p, b, sure);
    const double op = orient_filtered(a, b, p, sure);
    const bool sa = (oa > 0) | ((oa == 0) & tie), sb = (ob > 0) | ((ob == 0) & tie);
    // Bit 31 of the mask: a point on the edge's line is on its right.
    const bool right = (op < 0) | ((op == 0) & bool(m >> 31));
    flips ^= m & -std::uint32_t((sa != sb) & right);
  }
  return sure ? flips & 0x7FFFFFFFu : exact_flips(block, c, p);
}

// A record's groups in order, each block's flips by `flips` (the AVX2 kernel has its own copy:
// a function compiled for AVX2 cannot be inlined into one that is not).
template <class Flips>
inline std::uint32_t walk(const std::uint64_t* w, const Double2& point, Flips flips) {
  const Double2 p = point;
  for (;;) {
    const Group g = group_at(w, p);
    std::uint32_t mask = g.head & 0x7FFFFFFFu;
    const std::uint64_t* block = w + kHeadWords;
    for (std::uint32_t k = 0; k < g.blocks; ++k, block += kBlockWords)
      mask ^= flips(block, g.c, p, g.tie);
    std::uint32_t answer;
    if (group_answer(g, mask, block, answer, w)) return answer;
  }
}

std::uint32_t record_scalar(const std::uint64_t* w, const Double2& p) {
  return walk(w, p, scalar_flips);
}

#if KILN_POLYGON_X86
// The 64-bit lane masks of two registers as the four 32-bit lanes of one.
inline __m128i narrow(__m128d lo, __m128d hi) {
  return _mm_castps_si128(
      _mm_shuffle_ps(_mm_castpd_ps(lo), _mm_castpd_ps(hi), _MM_SHUFFLE(2, 0, 2, 0)));
}

// The four masks of the lanes set in `hit` (32-bit lanes), xored.
inline std::uint32_t xor_lanes(__m128i hit, const std::uint64_t* block) {
  const __m128i m = _mm_loadu_si128(reinterpret_cast<const __m128i*>(block + 16));
  __m128i x = _mm_and_si128(hit, m);
  x = _mm_xor_si128(x, _mm_shuffle_epi32(x, _MM_SHUFFLE(1, 0, 3, 2)));
  x = _mm_xor_si128(x, _mm_shuffle_epi32(x, _MM_SHUFFLE(2, 3, 0, 1)));
  return std::uint32_t(_mm_cvtsi128_si32(x)) & 0x7FFFFFFFu;
}

// Bit 31 of each mask, as all-ones 32-bit lanes: a point on the edge's line is on its right.
inline __m128i right_of_line(const std::uint64_t* block) {
  return _mm_srai_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(block + 16)), 31);
}

// ---- SSE2: two lanes per register ----

inline __m128d orient2(__m128d ax, __m128d ay, __m128d bx, __m128d by, __m128d cx, __m128d cy,
                       __m128d& sure) {
  const __m128d dl = _mm_mul_pd(_mm_sub_pd(ax, cx), _mm_sub_pd(by, cy));
  const __m128d dr = _mm_mul_pd(_mm_sub_pd(ay, cy), _mm_sub_pd(bx, cx));
  const __m128d det = _mm_sub_pd(dl, dr);
  const __m128d abs = _mm_castsi128_pd(_mm_set1_epi64x(0x7FFFFFFFFFFFFFFF));
  const __m128d bound = _mm_mul_pd(_mm_set1_pd(detail::kCcwErrBoundA),
                                   _mm_add_pd(_mm_and_pd(dl, abs), _mm_and_pd(dr, abs)));
  sure = _mm_and_pd(sure, _mm_cmpge_pd(_mm_and_pd(det, abs), bound));
  return det;
}

// Lanes l, l + 1: whether a and b lie apart from line c-p, p strictly right of the edge, p on
// its line, and the filter's certificate, as 64-bit lane masks.
struct Pair {
  __m128d apart, right, on_line, sure;
};

inline Pair pair_of(const std::uint64_t* block, int l, const Double2& c, const Double2& p,
                    __m128d tie) {
  auto lanes = [&](int axis) {
    return _mm_loadu_pd(reinterpret_cast<const double*>(block + 4 * axis + l));
  };
  const __m128d ax = lanes(0), ay = lanes(1), bx = lanes(2), by = lanes(3);
  const __m128d cx = _mm_set1_pd(c.x), cy = _mm_set1_pd(c.y);
  const __m128d px = _mm_set1_pd(p.x), py = _mm_set1_pd(p.y), zero = _mm_setzero_pd();
  __m128d ok = _mm_castsi128_pd(_mm_set1_epi32(-1));
  const __m128d oa = orient2(cx, cy, px, py, ax, ay, ok);  // orient2d(c, p, a)
  const __m128d ob = orient2(cx, cy, px, py, bx, by, ok);  // orient2d(c, p, b)
  const __m128d op = orient2(ax, ay, bx, by, px, py, ok);  // orient2d(a, b, p)
  const __m128d sa = _mm_or_pd(_mm_cmpgt_pd(oa, zero), _mm_and_pd(_mm_cmpeq_pd(oa, zero), tie));
  const __m128d sb = _mm_or_pd(_mm_cmpgt_pd(ob, zero), _mm_and_pd(_mm_cmpeq_pd(ob, zero), tie));
  return {_mm_xor_pd(sa, sb), _mm_cmplt_pd(op, zero), _mm_cmpeq_pd(op, zero), ok};
}

inline std::uint32_t sse2_flips(const std::uint64_t* block, const Double2& c, const Double2& p,
                                bool tie) {
  const __m128d t = _mm_castsi128_pd(_mm_set1_epi64x(-std::int64_t(tie)));
  const Pair lo = pair_of(block, 0, c, p, t), hi = pair_of(block, 2, c, p, t);
  if (_mm_movemask_pd(_mm_and_pd(lo.sure, hi.sure)) != 3) [[unlikely]]
    return exact_flips(block, c, p);
  const __m128i right =
      _mm_or_si128(narrow(lo.right, hi.right),
                   _mm_and_si128(narrow(lo.on_line, hi.on_line), right_of_line(block)));
  return xor_lanes(_mm_and_si128(narrow(lo.apart, hi.apart), right), block);
}

std::uint32_t record_sse2(const std::uint64_t* w, const Double2& p) {
  return walk(w, p, sse2_flips);
}

// ---- AVX2: a block in one register per coordinate ----

#define KILN_AVX2 __attribute__((target("avx2"), always_inline)) inline

KILN_AVX2 __m256d orient4(__m256d ax, __m256d ay, __m256d bx, __m256d by, __m256d cx, __m256d cy,
                          __m256d& sure) {
  const __m256d dl = _mm256_mul_pd(_mm256_sub_pd(ax, cx), _mm256_sub_pd(by, cy));
  const __m256d dr = _mm256_mul_pd(_mm256_sub_pd(ay, cy), _mm256_sub_pd(bx, cx));
  const __m256d det = _mm256_sub_pd(dl, dr);
  const __m256d abs = _mm256_castsi256_pd(_mm256_set1_epi64x(0x7FFFFFFFFFFFFFFF));
  const __m256d bound =
      _mm256_mul_pd(_mm256_set1_pd(detail::kCcwErrBoundA),
                    _mm256_add_pd(_mm256_and_pd(dl, abs), _mm256_and_pd(dr, abs)));
  sure = _mm256_and_pd(sure, _mm256_cmp_pd(_mm256_and_pd(det, abs), bound, _CMP_GE_OQ));
  return det;
}

KILN_AVX2 __m128i narrow4(__m256d v) {
  return narrow(_mm256_castpd256_pd128(v), _mm256_extractf128_pd(v, 1));
}

KILN_AVX2 std::uint32_t avx2_flips(const std::uint64_t* block, const Double2& c, const Double2& p,
                                   __m256d tie) {
  const double* v = reinterpret_cast<const double*>(block);
  const __m256d ax = _mm256_loadu_pd(v), ay = _mm256_loadu_pd(v + 4);
  const __m256d bx = _mm256_loadu_pd(v + 8), by = _mm256_loadu_pd(v + 12);
  const __m256d cx = _mm256_set1_pd(c.x), cy = _mm256_set1_pd(c.y);
  const __m256d px = _mm256_set1_pd(p.x), py = _mm256_set1_pd(p.y), zero = _mm256_setzero_pd();
  __m256d ok = _mm256_castsi256_pd(_mm256_set1_epi32(-1));
  const __m256d oa = orient4(cx, cy, px, py, ax, ay, ok);  // orient2d(c, p, a)
  const __m256d ob = orient4(cx, cy, px, py, bx, by, ok);  // orient2d(c, p, b)
  const __m256d op = orient4(ax, ay, bx, by, px, py, ok);  // orient2d(a, b, p)
  if (_mm256_movemask_pd(ok) != 15) [[unlikely]]
    return exact_flips(block, c, p);
  const __m256d sa = _mm256_or_pd(_mm256_cmp_pd(oa, zero, _CMP_GT_OQ),
                                  _mm256_and_pd(_mm256_cmp_pd(oa, zero, _CMP_EQ_OQ), tie));
  const __m256d sb = _mm256_or_pd(_mm256_cmp_pd(ob, zero, _CMP_GT_OQ),
                                  _mm256_and_pd(_mm256_cmp_pd(ob, zero, _CMP_EQ_OQ), tie));
  const __m128i right = _mm_or_si128(
      narrow4(_mm256_cmp_pd(op, zero, _CMP_LT_OQ)),
      _mm_and_si128(narrow4(_mm256_cmp_pd(op, zero, _CMP_EQ_OQ)), right_of_line(block)));
  return xor_lanes(_mm_and_si128(narrow4(_mm256_xor_pd(sa, sb)), right), block);
}

__attribute__((target("avx2"))) std::uint32_t record_avx2(const std::uint64_t* w,
                                                          const Double2& point) {
  const Double2 p = point;
  for (;;) {
    const Group g = group_at(w, p);
    const __m256d tie = _mm256_castsi256_pd(_mm256_set1_epi64x(-std::int64_t(g.tie)));
    std::uint32_t mask = g.head & 0x7FFFFFFFu;
    const std::uint64_t* block = w + kHeadWords;
    for (std::uint32_t k = 0; k < g.blocks; ++k, block += kBlockWords)
      mask ^= avx2_flips(block, g.c, p, tie);
    std::uint32_t answer;
    if (group_answer(g, mask, block, answer, w)) return answer;
  }
}
#endif

const char* name_of(KernelKind kind) {
  switch (kind) {
    case KernelKind::kSse2:
      return "sse2";
    case KernelKind::kAvx2:
      return "avx2";
    default:
      return "scalar";
  }
}

}  // namespace

bool supported(KernelKind kind) {
#if KILN_POLYGON_X86
  if (kind == KernelKind::kAvx2) return __builtin_cpu_supports("avx2");
  return true;
#else
  return kind == KernelKind::kScalar;
#endif
}

Kernel kernel(KernelKind kind) {
#if KILN_POLYGON_X86
  if (kind == KernelKind::kAvx2) return record_avx2;
  if (kind == KernelKind::kSse2) return record_sse2;
#endif
  return record_scalar;
}

KernelKind best_kernel() {
  if (const char* forced = std::getenv("KILN_POLYGON_KERNEL"); forced != nullptr && *forced) {
    for (const KernelKind k : {KernelKind::kScalar, KernelKind::kSse2, KernelKind::kAvx2})
      if (std::string_view(forced) == name_of(k)) {
        if (!supported(k))
          throw std::invalid_argument(std::string("KILN_POLYGON_KERNEL=") + forced +
                                      ": this CPU cannot run that kernel");
        return k;
      }
    throw std::invalid_argument(std::string("KILN_POLYGON_KERNEL=") + forced +
                                ": not scalar, sse2 or avx2");
  }
  for (const KernelKind k : {KernelKind::kAvx2, KernelKind::kSse2})
    if (supported(k)) return k;
  return KernelKind::kScalar;
}

}  // namespace kiln::polygon_records
