// The wide BVH traversal, written once over a vector abstraction and compiled once per
// instruction set by runtime/src/bvh_wide_kernel_<isa>.cpp. Not a header: each includer defines,
// in an anonymous namespace and before including it,
//   KILN_SIMD  the attributes of every function here (target instruction set, always_inline),
//   F4, F8     float vectors of 4 and 8 lanes: T, load, set1, add, sub, mul, div, max, min
//              (max(a, b) = a > b ? a : b and min(a, b) = a < b ? a : b, as x86 computes them, so
//              NaN handling equals the scalar slab test's), and lt, gt, le, eq returning lane bits;
//              F4 also has a lane-mask type M: lt_m, gt_m, eq_m, or_m, and_m, andnot_m (~a & b)
//              and bits(M);
//   KILN_WIDE_F16  (optional) the 16-lane float vector of 16-wide nodes (load, store, set1, add,
//              sub, mul, max, min, le); by default two F8 halves (PairVec);
//   KILN_WIDE_RANKS_AVX512  (optional, the AVX-512 kernel) its own paths: the ray set up in
//              vector registers, 16-wide children placed by rank, the any-hit push in one go.
// Everything here has internal linkage, so each instruction set's copy stays its own.
//
// The arithmetic per triangle is that of watertight.hpp operation for operation, per box that of
// ray_box.hpp with the far scale folded into the reciprocal; the same in every kernel (no
// contraction: -ffp-contract=off and no FMA target), so every kernel computes
// bit-identical distances and hits.

template <int W>
struct NodeVec;
template <>
struct NodeVec<4> {
  using V = F4;
};
template <>
struct NodeVec<8> {
  using V = F8;
};

/// 2N lanes as two N-lane vectors H (16-wide nodes on kernels without 16-lane registers).
template <class H, int N>
struct PairVec {
  struct T {
    typename H::T lo, hi;
  };
  KILN_SIMD static T load(const float* p) { return {H::load(p), H::load(p + N)}; }
  KILN_SIMD static void store(float* p, T a) { H::store(p, a.lo), H::store(p + N, a.hi); }
  KILN_SIMD static T set1(float x) { return {H::set1(x), H::set1(x)}; }
  KILN_SIMD static T add(T a, T b) { return {H::add(a.lo, b.lo), H::add(a.hi, b.hi)}; }
  KILN_SIMD static T sub(T a, T b) { return {H::sub(a.lo, b.lo), H::sub(a.hi, b.hi)}; }
  KILN_SIMD static T mul(T a, T b) { return {H::mul(a.lo, b.lo), H::mul(a.hi, b.hi)}; }
  KILN_SIMD static T max(T a, T b) { return {H::max(a.lo, b.lo), H::max(a.hi, b.hi)}; }
  KILN_SIMD static T min(T a, T b) { return {H::min(a.lo, b.lo), H::min(a.hi, b.hi)}; }
  KILN_SIMD static unsigned le(T a, T b) { return H::le(a.lo, b.lo) | H::le(a.hi, b.hi) << N; }
};
#ifndef KILN_WIDE_F16
#define KILN_WIDE_F16 PairVec<F8, 8>
#endif
template <>
struct NodeVec<16> {
  using V = KILN_WIDE_F16;
};

/// Per-ray constants of the box test, splatted.
template <class V>
struct BoxLanes {
  typename V::T org[3], inv[3], inv_far[3];  // inv_far = inv x kFarScale
  int near[3];  // bounds[axis][near] is the entry plane (1 = max for a negative direction)
};

#ifndef KILN_WIDE_RANKS_AVX512
template <class V>
KILN_SIMD BoxLanes<V> box_lanes(const Ray& ray) {
  const BoxRay r = prepare_box_ray(ray);
  BoxLanes<V> b;
  for (int a = 0; a < 3; ++a) {
    b.org[a] = V::set1(r.org[a]);
    b.inv[a] = V::set1(r.inv_dir[a]);
    // Scaling the reciprocal instead of each far distance: the same number of roundings, so
    // pbrt's 1 + 2 gamma(3) still covers them (ray_box.hpp), one multiply less per axis.
    b.inv_far[a] = V::set1(r.inv_dir[a] * kFarScale);
    b.near[a] = r.negative[a];
  }
  return b;
}
#endif

/// Per-ray constants of the triangle test, splatted once per ray rather than per leaf.
struct TriLanes {
  F4::T org[3], shear[3];  // origin on the permuted axes kx, ky, kz; sx, sy, sz
  std::size_t row[3];      // byte offset of axis kx, ky, kz in a corner's rows (v[c][axis])
};

#ifndef KILN_WIDE_RANKS_AVX512
KILN_SIMD TriLanes tri_lanes(const Ray& ray) {
  const WatertightRay r = prepare_watertight(ray);
  TriLanes t;
  const int axis[3] = {r.kx, r.ky, r.kz};
  const float shear[3] = {r.sx, r.sy, r.sz};
  for (int i = 0; i < 3; ++i) {
    t.org[i] = F4::set1(r.org[axis[i]]);
    t.shear[i] = F4::set1(shear[i]);
    t.row[i] = std::size_t(axis[i]) * sizeof(float) * format::kBvhPacketSize;
  }
  return t;
}
#else
// The AVX-512 kernel sets a ray up in vector registers: one division for the three reciprocals,
// one for the three shears, the permuted axes by a lane permute instead of through memory. The
// same operations on the same operands as prepare_box_ray and prepare_watertight, so the same
// bits. The entry planes come from the direction's sign bits, not from the reciprocal's sign: the
// same planes (1 / -0 = -inf; a NaN component makes both planes' distances NaN, which the max and
// min drop either way), but the node's first loads need not wait for the division.
KILN_SIMD __m128 ray_org4(const Ray& ray) {  // x, y, z, tmin
  return _mm_loadu_ps(reinterpret_cast<const float*>(&ray));
}
KILN_SIMD __m128 ray_dir4(const Ray& ray) {  // x, y, z, tmax
  return _mm_loadu_ps(reinterpret_cast<const float*>(&ray) + 4);
}

template <class V>
KILN_SIMD BoxLanes<V> box_lanes(const Ray& ray) {
  static_assert(sizeof(Ray) == 8 * sizeof(float));
  const __m128 o = ray_org4(ray), d = ray_dir4(ray);
  const __m128 inv = _mm_div_ps(_mm_set1_ps(1.0f), d);  // lane 3 (1 / tmax) unused
  // Scaling the reciprocal instead of each far distance: the same number of roundings, so
  // pbrt's 1 + 2 gamma(3) still covers them (ray_box.hpp), one multiply less per axis.
  const __m128 inv_far = _mm_mul_ps(inv, _mm_set1_ps(kFarScale));
  const unsigned sign = unsigned(_mm_movemask_ps(d));
  BoxLanes<V> b;
  for (int a = 0; a < 3; ++a) {
    b.org[a] = V::set1(o[a]);
    b.inv[a] = V::set1(inv[a]);
    b.inv_far[a] = V::set1(inv_far[a]);
    b.near[a] = int(sign >> a & 1u);
  }
  return b;
}

// prepare_watertight's axes: kz the largest |d| by the same three comparisons (ax > ay, ax > az,
// ay > az, in one compare, indexing a table made for that bit order), kx and ky swapped for d[kz]
// < 0.
KILN_SIMD __m128i watertight_axes(__m128 d) {
  const __m128 a = _mm_andnot_ps(_mm_set1_ps(-0.0f), d);
  const __m128 lhs = _mm_permute_ps(a, _MM_SHUFFLE(1, 1, 0, 0));  // ax, ax, ay
  const __m128 rhs = _mm_permute_ps(a, _MM_SHUFFLE(2, 2, 2, 1));  // ay, az, az
  const unsigned index = unsigned(_mm_movemask_ps(_mm_cmpgt_ps(lhs, rhs))) & 7u;
  const unsigned kz = 0x1210222u >> (4 * index) & 3u;
  unsigned kx = 0x021u >> (4 * kz) & 3u, ky = 0x102u >> (4 * kz) & 3u;
  const unsigned negative = unsigned(_mm_movemask_ps(_mm_cmplt_ps(d, _mm_setzero_ps())));
  const unsigned swap = (kx ^ ky) & (0u - (negative >> kz & 1u));
  kx ^= swap, ky ^= swap;
  return _mm_setr_epi32(int(kx), int(ky), int(kz), int(kz));
}

KILN_SIMD TriLanes tri_lanes(const Ray& ray) {
  const __m128i axes = watertight_axes(ray_dir4(ray));
  const __m128 d = _mm_permutevar_ps(ray_dir4(ray), axes);  // d[kx], d[ky], d[kz], d[kz]
  const __m128 o = _mm_permutevar_ps(ray_org4(ray), axes);
  const __m128 num = _mm_blend_ps(d, _mm_set1_ps(1.0f), 0xC);     // d[kx], d[ky], 1, 1
  const __m128 shear = _mm_div_ps(num, _mm_permute_ps(d, 0xAA));  // sx, sy, sz = 1 / d[kz]
  TriLanes t;
  t.org[0] = _mm_permute_ps(o, 0x00), t.org[1] = _mm_permute_ps(o, 0x55);
  t.org[2] = _mm_permute_ps(o, 0xAA);
  t.shear[0] = _mm_permute_ps(shear, 0x00), t.shear[1] = _mm_permute_ps(shear, 0x55);
  t.shear[2] = _mm_permute_ps(shear, 0xAA);
  const std::size_t row = sizeof(float) * format::kBvhPacketSize;
  t.row[0] = std::size_t(_mm_extract_epi32(axes, 0)) * row;
  t.row[1] = std::size_t(_mm_extract_epi32(axes, 1)) * row;
  t.row[2] = std::size_t(_mm_extract_epi32(axes, 2)) * row;
  return t;
}
#endif

// One box plane of every child: side 0 min, 1 max.
template <class V, int W>
KILN_SIMD typename V::T plane(const format::BvhWideNode<W>& n, int axis, int side) {
  return V::load(n.bounds[axis][side]);
}
template <class V, int W>
KILN_SIMD typename V::T plane(const format::BvhQuantizedNode<W>& n, int axis, int side) {
  const typename V::T scale = V::set1(format::bvh_quantized_scale(n.exponent[axis]));
  return V::add(V::set1(n.origin[axis]), V::mul(V::load_u8(n.q[axis][side]), scale));
}

// Entry distances of all W children into `dist`; returns the bits of the children entered.
template <class Node, class V>
KILN_SIMD unsigned test_children(const Node& n, const BoxLanes<V>& r, typename V::T tmin,
                                 typename V::T tmax, float* dist) {
  for (int a = 0; a < 3; ++a) {
    const typename V::T lo = plane<V>(n, a, r.near[a]);
    const typename V::T hi = plane<V>(n, a, 1 - r.near[a]);
    const typename V::T t0 = V::mul(V::sub(lo, r.org[a]), r.inv[a]);
    const typename V::T t1 = V::mul(V::sub(hi, r.org[a]), r.inv_far[a]);
    tmin = V::max(t0, tmin);
    tmax = V::min(t1, tmax);
  }
  V::store(dist, tmin);
  return V::le(tmin, tmax);
}

// The closest (or, kAny, the first) lane of a packet hit in (tmin, tmax); -1 when none.
template <bool kAny>
KILN_SIMD int test_packet(const format::BvhTrianglePacket& p, const Ray& ray, const TriLanes& l,
                          float tmin, float tmax, float& t_out, float& u_out, float& v_out) {
  using T = F4::T;
  T x[3], y[3], z[3];
  for (int c = 0; c < 3; ++c) {
    const char* rows = reinterpret_cast<const char*>(p.v[c]);
    const T px = F4::sub(F4::load(reinterpret_cast<const float*>(rows + l.row[0])), l.org[0]);
    const T py = F4::sub(F4::load(reinterpret_cast<const float*>(rows + l.row[1])), l.org[1]);
    z[c] = F4::sub(F4::load(reinterpret_cast<const float*>(rows + l.row[2])), l.org[2]);
    x[c] = F4::sub(px, F4::mul(l.shear[0], z[c]));
    y[c] = F4::sub(py, F4::mul(l.shear[1], z[c]));
  }
  const T u = F4::sub(F4::mul(x[2], y[1]), F4::mul(y[2], x[1]));
  const T v = F4::sub(F4::mul(x[0], y[2]), F4::mul(y[0], x[2]));
  const T w = F4::sub(F4::mul(x[1], y[0]), F4::mul(y[1], x[0]));
  const T zero = F4::set1(0.0f);
  // Lanes with an exact zero edge function take the scalar test (double re-evaluation). No
  // branch before the division (whether a lane passes its edges is hard to predict, a division
  // is cheaper than the mispredicted exit), and the lane masks are combined in registers, then
  // turned into bits once each.
  using M = typename F4::M;
  const M exact_m = F4::or_m(F4::or_m(F4::eq_m(u, zero), F4::eq_m(v, zero)), F4::eq_m(w, zero));
  const M negative = F4::or_m(F4::or_m(F4::lt_m(u, zero), F4::lt_m(v, zero)), F4::lt_m(w, zero));
  const M positive = F4::or_m(F4::or_m(F4::gt_m(u, zero), F4::gt_m(v, zero)), F4::gt_m(w, zero));
  const T det = F4::add(F4::add(u, v), w);
  const T sz = l.shear[2];
  const T t_scaled = F4::add(F4::add(F4::mul(u, F4::mul(sz, z[0])), F4::mul(v, F4::mul(sz, z[1]))),
                             F4::mul(w, F4::mul(sz, z[2])));
  const T t = F4::div(t_scaled, det);
  const M out = F4::or_m(F4::or_m(F4::and_m(negative, positive), exact_m), F4::eq_m(det, zero));
  const M in_range = F4::and_m(F4::gt_m(t, F4::set1(tmin)), F4::lt_m(t, F4::set1(tmax)));
  const unsigned exact = F4::bits(exact_m);
  const unsigned ok = F4::bits(F4::andnot_m(out, in_range));
  if ((ok | exact) == 0) return -1;
  alignas(16) float ts[4], vs[4], ws[4], dets[4];
  F4::store(ts, t), F4::store(vs, v), F4::store(ws, w), F4::store(dets, det);
  int best = -1;
  for (unsigned todo = ok | exact; todo != 0; todo &= todo - 1) {
    const int lane = __builtin_ctz(todo);
    float lt, lu, lv;
    if (exact >> lane & 1u) {
      const format::Float3 a{p.v[0][0][lane], p.v[0][1][lane], p.v[0][2][lane]};
      const format::Float3 b{p.v[1][0][lane], p.v[1][1][lane], p.v[1][2][lane]};
      const format::Float3 c{p.v[2][0][lane], p.v[2][1][lane], p.v[2][2][lane]};
      // Rare (an exact zero edge function): the scalar ray is set up here, not per ray.
      if (!intersect_watertight(prepare_watertight(ray), a, b, c, tmin, tmax, lt, lu, lv)) continue;
    } else {
      if (!(ts[lane] < tmax)) continue;
      lt = ts[lane], lu = vs[lane] / dets[lane], lv = ws[lane] / dets[lane];
    }
    // Lane order, strictly closer: the scalar BVH's order of triangle tests within a leaf.
    tmax = lt, t_out = lt, u_out = lu, v_out = lv, best = lane;
    if constexpr (kAny) return best;
  }
  return best;
}

/// A child to visit: its word, packet count (or, interior, prefetch lines) and entry distance;
/// in the AVX-512 kernel also its depth below the root (kPrefetchDepth).
struct WideEntry {
  std::uint32_t word, packets;
  float t;
#ifdef KILN_WIDE_RANKS_AVX512
  std::uint32_t depth;
#endif
};

KILN_SIMD WideEntry entry(std::uint32_t word, std::uint32_t packets, float t,
                          [[maybe_unused]] std::uint32_t depth) {
#ifdef KILN_WIDE_RANKS_AVX512
  return {word, packets, t, depth};
#else
  return {word, packets, t};
#endif
}

// Float bits made to sort as unsigned integers (negative distances included).
KILN_SIMD std::uint32_t sortable(float f) {
  std::uint32_t bits;
  std::memcpy(&bits, &f, sizeof bits);
  return bits ^ (std::uint32_t(std::int32_t(bits) >> 31) | 0x80000000u);
}

#ifdef KILN_WIDE_RANKS_AVX512
inline constexpr bool kRanks16 = true;

template <class Node>
KILN_SIMD void prefetch_child(std::uint32_t word, std::uint32_t packets, const std::byte* arena);

// Closest hit, 16-wide, three or more entered children (bits `mask`): each child's rank in the
// insertion sort's order of next_child (keys (sortable distance, slot), farthest first) counted
// in one compare of all 16 keys, and the child written straight to its stack place; the nearest
// (the last place) is returned. The same order as the insertion sort (keys are unique), so the
// same hits as every other kernel, without its data-dependent branches. Writes one entry more
// than it pushes: a node at depth D (root 1) finds at most (W - 1)(D - 1) entries on the stack
// and writes up to index (W - 1) D, which the stack's (W - 1) kBvhMaxDepth + 1 entries hold.
// Each child is prefetched as it is placed (one walk over the entered children, not two).
KILN_SIMD WideEntry ranked_children16(const format::BvhWideNode<16>& n, unsigned mask,
                                      const float* dist, WideEntry* stack, std::uint32_t& top,
                                      const std::byte* arena, std::uint32_t depth, bool prefetch) {
  const __m512i bits = _mm512_castps_si512(_mm512_loadu_ps(dist));
  const __m512i keys = _mm512_xor_si512(
      bits, _mm512_or_si512(_mm512_srai_epi32(bits, 31), _mm512_set1_epi32(int(0x80000000u))));
  alignas(64) std::uint32_t key[16];
  _mm512_store_si512(key, keys);
  WideEntry* base = stack + top;
  const unsigned count = unsigned(__builtin_popcount(mask));
  for (unsigned todo = mask; todo != 0; todo &= todo - 1) {
    const int s = __builtin_ctz(todo);
    const __m512i k = _mm512_set1_epi32(int(key[s]));
    const __mmask16 after = __mmask16(mask & ~((2u << s) - 1u));  // entered slots above s
    const unsigned farther = _mm512_mask_cmpgt_epu32_mask(__mmask16(mask), keys, k) |
                             _mm512_mask_cmpeq_epu32_mask(after, keys, k);
    if (prefetch) prefetch_child<format::BvhWideNode<16>>(n.child[s], n.packets[s], arena);
    base[__builtin_popcount(farther)] = entry(n.child[s], n.packets[s], dist[s], depth);
  }
  top += count - 1;
  return stack[top];
}

// Any hit, 16-wide: the entered children after the first (bits `rest`) pushed in one go, no loop
// over them. The stack is two arrays (words, packet counts; any hit needs no distances) growing
// downwards from index kAnyStack16: the children are compressed into the low lanes in slot order
// and stored below the top with a masked store, so the lowest slot lies lowest and they pop in
// slot order, as next_child pushes them. (A child popped right after its push waits for the
// masked store, which does not forward; making every next child go through the stack that way
// was 20-30 % slower, so the first entered child is still read from the node.)
inline constexpr std::uint32_t kAnyStack16 = 15 * format::kBvhMaxDepth;
KILN_SIMD void push_any16(const format::BvhWideNode<16>& n, unsigned rest, std::uint32_t* words,
                          std::uint32_t* packets, std::uint32_t& top) {
  const unsigned count = unsigned(__builtin_popcount(rest));
  const __m512i child = _mm512_loadu_si512(n.child);
  const __m512i packet =
      _mm512_cvtepu8_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(n.packets)));
  const __mmask16 low = __mmask16((1u << count) - 1u);
  top -= count;
  _mm512_mask_storeu_epi32(words + top, low, _mm512_maskz_compress_epi32(__mmask16(rest), child));
  _mm512_mask_storeu_epi32(packets + top, low,
                           _mm512_maskz_compress_epi32(__mmask16(rest), packet));
}
#else
inline constexpr bool kRanks16 = false;
#endif

// Of the entered children of `n` (bits `mask`, at least one), returns the one to visit next and
// pushes the others: kOrdered, nearest next and the rest farthest first (so nearer ones pop
// first); otherwise in slot order (the collapse orders slots for any-hit rays).
template <int W, bool kOrdered, class Node>
KILN_SIMD WideEntry next_child(const Node& n, unsigned mask, const float* dist, WideEntry* stack,
                               std::uint32_t& top, [[maybe_unused]] const std::byte* arena,
                               std::uint32_t depth, [[maybe_unused]] bool prefetch) {
  int slot = __builtin_ctz(mask);
  mask &= mask - 1;
  if (mask == 0) return entry(n.child[slot], n.packets[slot], dist[slot], depth);
  if constexpr (kOrdered) {
    const int second = __builtin_ctz(mask);
    mask &= mask - 1;
    if (mask == 0) {  // two children, the common case: one compare
      const int near = dist[second] < dist[slot] ? second : slot;
      const int far = near == slot ? second : slot;
      stack[top++] = entry(n.child[far], n.packets[far], dist[far], depth);
      return entry(n.child[near], n.packets[near], dist[near], depth);
    }
#ifdef KILN_WIDE_RANKS_AVX512
    if constexpr (W == 16)
      return ranked_children16(n, mask | 1u << slot | 1u << second, dist, stack, top, arena, depth,
                               prefetch);
#endif
    std::uint64_t keys[W];
    keys[0] = std::uint64_t(sortable(dist[slot])) << 32 | std::uint32_t(slot);
    int count = 1;
    for (mask |= 1u << second; mask != 0; mask &= mask - 1) {
      const int s = __builtin_ctz(mask);
      const std::uint64_t key = std::uint64_t(sortable(dist[s])) << 32 | std::uint32_t(s);
      int j = count++;
      for (; j > 0 && keys[j - 1] < key; --j) keys[j] = keys[j - 1];  // farthest first
      keys[j] = key;
    }
    for (int k = 0; k < count - 1; ++k) {
      const int s = int(keys[k] & 0xFu);
      stack[top++] = entry(n.child[s], n.packets[s], dist[s], depth);
    }
    slot = int(keys[count - 1] & 0xFu);
  } else {
    // Pushed highest slot first, so they pop in slot order after the lowest.
    while (mask != 0) {
      const int s = 31 - __builtin_clz(mask);
      mask &= ~(1u << s);
      stack[top++] = entry(n.child[s], n.packets[s], dist[s], depth);
    }
  }
  return entry(n.child[slot], n.packets[slot], dist[slot], depth);
}

/// AVX-512, 16-wide closest hit: the children of nodes at depths below this (the root is 0) are
/// not prefetched. Those top levels (1 + 16 nodes, whose children are the 272 nodes of levels 1
/// and 2, about 140 KiB with their first leaf lines) stay in the L2 cache across rays, so their
/// prefetches only took issue slots: without them primary rays gain 6-11 %.
inline constexpr std::uint32_t kPrefetchDepth = 2;

/// The nodes' lines, and at most this many lines of an interior child's leaf packets, are loaded
/// ahead when a child is entered.
inline constexpr std::uint32_t kPrefetchLeafLines = 4;

// Starts loading a child while other work goes on: a node with the first lines of its own leaf
// packets, which follow it in the arena (so a node's leaves are on their way one level before
// they are reached), or a leaf's first two packets. On meshes larger than the caches, traversal
// waits on memory more than it computes.
template <class Node>
KILN_SIMD void prefetch_child(std::uint32_t word, std::uint32_t packets, const std::byte* arena) {
  const char* p = reinterpret_cast<const char*>(arena) +
                  std::size_t(word & ~format::kBvhLeafFlag) * format::kBvhArenaUnit;
  std::size_t bytes;
  if (word & format::kBvhLeafFlag) {
    bytes = std::min<std::size_t>(packets, 2) * sizeof(format::BvhTrianglePacket);
    __builtin_prefetch(p + bytes - 1);  // a leaf need not start on a line
  } else {
    bytes =
        sizeof(Node) + format::kBvhArenaLine * std::min<std::uint32_t>(packets, kPrefetchLeafLines);
  }
  for (std::size_t line = 0; line < bytes; line += format::kBvhArenaLine)
    __builtin_prefetch(p + line);
}

// Closest hit: every entered child, before they are sorted (the nearest is visited next, the
// others are popped in distance order and most of them are visited).
template <class Node>
KILN_SIMD void prefetch_children(const Node& n, unsigned mask, const std::byte* arena) {
  for (; mask != 0; mask &= mask - 1) {
    const int slot = __builtin_ctz(mask);
    prefetch_child<Node>(n.child[slot], n.packets[slot], arena);
  }
}

/// The one traversal: kAny stops at the first hit and takes the entered children in slot order.
template <class Node, int W, bool kAny, bool kCount>
KILN_SIMD Hit traverse_wide(const BvhWideView& view, const Ray& ray, Cost* cost) {
  using V = typename NodeVec<W>::V;
  const std::byte* arena = view.arena().data();
  const BoxLanes<V> box = box_lanes<V>(ray);
  const TriLanes tri = tri_lanes(ray);
  const typename V::T tmin = V::set1(ray.tmin);
  Hit hit;
  hit.t = ray.tmax;
  const format::BvhTrianglePacket* best_packet = nullptr;
  int best_lane = 0;
  WideEntry stack[(W - 1) * format::kBvhMaxDepth + 1];
#ifdef KILN_WIDE_RANKS_AVX512
  // Any hit, 16-wide: the stack as two arrays (push_any16); the masked stores write only the
  // entries pushed, at most (W - 1) per level.
  [[maybe_unused]] std::uint32_t any_words[kAny && W == 16 ? kAnyStack16 : 1];
  [[maybe_unused]] std::uint32_t any_packets[kAny && W == 16 ? kAnyStack16 : 1];
#endif
  std::uint32_t top = 0;
#ifdef KILN_WIDE_RANKS_AVX512
  if constexpr (kAny && W == 16) top = kAnyStack16;
#endif
  alignas(32) float dist[W];
  WideEntry e = entry(0, 0, ray.tmin, 0);
  for (;;) {
    while ((e.word & format::kBvhLeafFlag) == 0) {
      const auto& n =
          *reinterpret_cast<const Node*>(arena + std::size_t(e.word) * format::kBvhArenaUnit);
      if constexpr (kCount) cost->nodes += 1;
      const unsigned mask = test_children<Node, V>(n, box, tmin, V::set1(hit.t), dist);
      if (mask == 0) goto pop;
#ifdef KILN_WIDE_RANKS_AVX512
      const bool prefetch = W != 16 || e.depth >= kPrefetchDepth;
      const std::uint32_t below = e.depth + 1;
#else
      constexpr bool prefetch = true;
      constexpr std::uint32_t below = 0;
#endif
      // Any hit: only the child visited next. The others wait on the stack until its whole
      // subtree is done, and are not visited at all when the ray is blocked in it.
      // (16-wide with ranks: three or more children are prefetched as they are placed.)
      if constexpr (!kAny)
        if ((!(kRanks16 && W == 16) || __builtin_popcount(mask) < 3) && prefetch)
          prefetch_children(n, mask, arena);
#ifdef KILN_WIDE_RANKS_AVX512
      if constexpr (kAny && W == 16) {
        const int slot = __builtin_ctz(mask);
        push_any16(n, mask & (mask - 1), any_words, any_packets, top);
        e = entry(n.child[slot], n.packets[slot], 0.0f, 0);
      } else
#endif
        e = next_child<W, !kAny>(n, mask, dist, stack, top, arena, below, prefetch);
      if constexpr (kAny) prefetch_child<Node>(e.word, e.packets, arena);
    }
    {
      const auto* p = reinterpret_cast<const format::BvhTrianglePacket*>(
          arena + std::size_t(e.word & ~format::kBvhLeafFlag) * format::kBvhArenaUnit);
      for (const auto* end = p + e.packets; p < end; ++p) {
        if constexpr (kCount) cost->tests += format::kBvhPacketSize;
        const int lane = test_packet<kAny>(*p, ray, tri, ray.tmin, hit.t, hit.t, hit.u, hit.v);
        if (lane < 0) continue;
        best_packet = p, best_lane = lane;
        if constexpr (kAny) {
          hit.prim = p->prim[lane];
          return hit;
        }
      }
    }
  pop:  // the next subtree that can still hold a closer hit
    do {
#ifdef KILN_WIDE_RANKS_AVX512
      if constexpr (kAny && W == 16) {
        if (top == kAnyStack16) return Hit{};
        e = entry(any_words[top], any_packets[top], 0.0f, 0);
        ++top;
        continue;
      }
#endif
      if (top == 0) {
        if (best_packet == nullptr) return Hit{};
        hit.prim = best_packet->prim[best_lane];
        return hit;
      }
      e = stack[--top];
    } while (!kAny && e.t > hit.t);
  }
}

// The entry points carry the target attribute but are not always_inline (they are called
// through the table).
#define KILN_WIDE_KERNEL_TABLE(NAME)                                                 \
  template <class Node, int W>                                                       \
  KILN_SIMD_ENTRY Hit NAME##_closest(const BvhWideView& v, const Ray& r) {           \
    return traverse_wide<Node, W, false, false>(v, r, nullptr);                      \
  }                                                                                  \
  template <class Node, int W>                                                       \
  KILN_SIMD_ENTRY Hit NAME##_any(const BvhWideView& v, const Ray& r) {               \
    return traverse_wide<Node, W, true, false>(v, r, nullptr);                       \
  }                                                                                  \
  template <class Node, int W>                                                       \
  KILN_SIMD_ENTRY Hit NAME##_counting(const BvhWideView& v, const Ray& r, Cost& c) { \
    return traverse_wide<Node, W, false, true>(v, r, &c);                            \
  }                                                                                  \
  template <class Node, int W>                                                       \
  constexpr BvhWideKernel table_of() {                                               \
    return {NAME##_closest<Node, W>, NAME##_any<Node, W>, NAME##_counting<Node, W>}; \
  }                                                                                  \
  const BvhWideKernel k##NAME[2][2] = {                                              \
      {table_of<format::BvhNode4, 4>(), table_of<format::BvhNode8, 8>()},            \
      {table_of<format::BvhQNode4, 4>(), table_of<format::BvhQNode8, 8>()}};         \
  const BvhWideKernel k##NAME##16 = table_of<format::BvhNode16, 16>();
