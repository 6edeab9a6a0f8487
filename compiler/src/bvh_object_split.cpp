// Object splits of the SBVH builder on presorted per-axis arrays.
#include <algorithm>
#include <cstddef>
#include <utility>
#include <vector>

#include "bvh_build_simd.hpp"
#include "bvh_splits.hpp"
#include "huge_pages.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln {

namespace {

struct KeyIndex {
  std::uint64_t key;
  std::uint32_t index;
  bool operator<(const KeyIndex& o) const { return key < o.key; }  // keys are unique
};

}  // namespace

namespace {

// LSD radix sort of unique 64-bit keys on their bits from `low_bit` up, 11 bits a pass,
// skipping the passes whose digit is the same for every key (the high bits of the primitive ids,
// mostly). With low_bit 0 it gives the order std::sort gives; with low_bit 32 (the centroid
// alone) it gives that order too when the keys come in ascending order of their low 32 bits
// (the primitive ids): the sort is stable, so ties on the centroid keep that order.
void radix_sort(std::vector<KeyIndex>& keys, int low_bit) {
  constexpr int kBits = 11;
  constexpr std::size_t kBuckets = std::size_t(1) << kBits;
  const int passes = (64 - low_bit + kBits - 1) / kBits;
  std::vector<std::uint32_t> count(std::size_t(passes) * kBuckets, 0);
  for (const KeyIndex& k : keys)
    for (int p = 0; p < passes; ++p)
      ++count[p * kBuckets + ((k.key >> (low_bit + p * kBits)) & (kBuckets - 1))];
  std::vector<KeyIndex> tmp = huge_vector<KeyIndex>(keys.size());
  for (int p = 0; p < passes; ++p) {
    std::uint32_t* c = count.data() + p * kBuckets;
    if (std::any_of(c, c + kBuckets, [&](std::uint32_t n) { return n == keys.size(); })) continue;
    std::uint32_t sum = 0;
    for (std::size_t b = 0; b < kBuckets; ++b) sum += std::exchange(c[b], sum);
    const int shift = low_bit + p * kBits;
    for (const KeyIndex& k : keys) tmp[c[(k.key >> shift) & (kBuckets - 1)]++] = k;
    keys.swap(tmp);
  }
}

// The same order as radix_sort, by `chunks` fixed chunks of the keys on up to `threads` threads:
// each pass counts the chunks apart, and each chunk scatters after the earlier chunks' keys of
// the same digit (the stable order one scatter gives).
void radix_sort_chunked(std::vector<KeyIndex>& keys, int low_bit, std::size_t chunks,
                        unsigned threads) {
  constexpr int kBits = 11;
  constexpr std::size_t kBuckets = std::size_t(1) << kBits;
  const int passes = (64 - low_bit + kBits - 1) / kBits;
  const std::size_t n = keys.size(), chunk = (n + chunks - 1) / chunks;
  std::vector<std::uint32_t> count(chunks * kBuckets);
  std::vector<KeyIndex> tmp = huge_vector<KeyIndex>(n);
  for (int p = 0; p < passes; ++p) {
    const int shift = low_bit + p * kBits;
    parallel_for(chunks, threads, [&](std::size_t c) {
      std::uint32_t* h = count.data() + c * kBuckets;
      std::fill(h, h + kBuckets, 0u);
      for (std::size_t i = c * chunk; i < std::min(n, (c + 1) * chunk); ++i)
        ++h[(keys[i].key >> shift) & (kBuckets - 1)];
    });
    std::uint32_t sum = 0;
    bool constant = false;  // one digit for every key: the pass would change nothing
    for (std::size_t b = 0; b < kBuckets; ++b) {
      const std::uint32_t before = sum;
      for (std::size_t c = 0; c < chunks; ++c) sum += std::exchange(count[c * kBuckets + b], sum);
      constant |= sum - before == n;
    }
    if (constant) continue;
    parallel_for(chunks, threads, [&](std::size_t c) {
      std::uint32_t* h = count.data() + c * kBuckets;
      for (std::size_t i = c * chunk; i < std::min(n, (c + 1) * chunk); ++i)
        tmp[h[(keys[i].key >> shift) & (kBuckets - 1)]++] = keys[i];
    });
    keys.swap(tmp);
  }
}

constexpr std::size_t kRadixSort = 2048;  // radix sort from this many references, std::sort below

}  // namespace

void sort_by_centroid(std::span<const PrimRef> refs, int axis, std::vector<PrimRef>& out,
                      unsigned threads) {
  // Sorting 12-byte keys, then gathering once, costs a fraction of sorting 28-byte references.
  const std::size_t n = refs.size();
  const std::size_t chunks = n >= kRadixSort ? std::max(1u, threads) : 1;
  const std::size_t chunk = (n + chunks - 1) / chunks;
  std::vector<KeyIndex> keys = huge_vector<KeyIndex>(n);
  std::vector<char> prim_order(chunks, 1);  // ids ascending (the root's refs): centroids only
  parallel_for(chunks, threads, [&](std::size_t c) {
    for (std::size_t i = c * chunk; i < std::min(n, (c + 1) * chunk); ++i) {
      keys[i] = {centroid_key(refs[i], axis), std::uint32_t(i)};
      prim_order[c] &= i == 0 || refs[i - 1].prim < refs[i].prim;
    }
  });
  const int low_bit =
      std::all_of(prim_order.begin(), prim_order.end(), [](char o) { return o; }) ? 32 : 0;
  if (n < kRadixSort)
    std::sort(keys.begin(), keys.end());
  else if (chunks == 1)
    radix_sort(keys, low_bit);
  else
    radix_sort_chunked(keys, low_bit, chunks, threads);
  reserve_huge(out, n);
  out.resize(n);
  parallel_for(chunks, threads, [&](std::size_t c) {
    for (std::size_t i = c * chunk; i < std::min(n, (c + 1) * chunk); ++i)
      out[i] = refs[keys[i].index];
  });
}

namespace {

// A reference's corners as vectors, lane 3 zero: one unaligned load of the 16 bytes from the
// corner (the reference's 28 bytes cover both: min xyz + max.x, max xyz + prim), the fourth
// lane masked off.
static_assert(sizeof(PrimRef) == 28 && offsetof(PrimRef, box) == 0 && sizeof(format::Box3f) == 24);
bvh_simd::V4 lower(const PrimRef& r) {
  return bvh_simd::xyz(bvh_simd::loadu(&r.box.min.x));
}
bvh_simd::V4 upper(const PrimRef& r) {
  return bvh_simd::xyz(bvh_simd::loadu(&r.box.max.x));
}

}  // namespace

namespace {

// The exact sweep on one axis: replaces `best` with a cheaper split (the first position wins
// ties). Boxes grown on vectors, half areas as Box3f's (bvh_build_simd.hpp: the same bits).
void sweep_on_axis(const PrimRef* s, std::size_t n, float node_area, const BvhBuildOptions& o,
                   int axis, std::vector<float>& right_area, ObjectSplit& best) {
  right_area.resize(n);  // of the references [i, n) on the axis
  bvh_simd::VBox acc;
  for (std::size_t i = n; i-- > 1;) {
    acc.grow(lower(s[i]), upper(s[i]));
    right_area[i] = bvh_simd::half_area(acc);
  }
  bvh_simd::VBox left;
  for (std::size_t i = 0; i + 1 < n; ++i) {
    left.grow(lower(s[i]), upper(s[i]));
    const float cost = o.traversal_cost + o.intersection_cost *
                                              (bvh_simd::half_area(left) * float(i + 1) +
                                               right_area[i + 1] * float(n - i - 1)) /
                                              node_area;
    if (cost < best.cost) best.cost = cost, best.axis = axis, best.left_count = i + 1;
  }
}

}  // namespace

ObjectSplit find_sweep_split(const SortedRefs& refs, const format::Box3f& node_box,
                             const BvhBuildOptions& o, unsigned threads) {
  const float node_area = node_box.half_area();
  ObjectSplit best;
  const std::size_t n = refs.size();
  if (node_area <= 0.0f || n < 2) return best;
  if (threads == 1 || n < kParallelSweep) {
    thread_local std::vector<float> right_area;
    for (int axis = 0; axis < 3; ++axis)
      sweep_on_axis(refs.axis[axis].data(), n, node_area, o, axis, right_area, best);
  } else {
    // Each axis apart, then the first cheapest in axis order: what one pass over the axes in
    // turn finds.
    ObjectSplit per_axis[3];
    std::vector<float> right_area[3];
    parallel_for(3, threads, [&](std::size_t a) {
      sweep_on_axis(refs.axis[a].data(), n, node_area, o, int(a), right_area[a], per_axis[a]);
    });
    for (const ObjectSplit& s : per_axis)
      if (s.cost < best.cost) best = s;
  }
  // The winner's two boxes, grown once more here rather than stored at every step.
  const auto& s = refs.axis[best.axis];
  for (std::size_t i = 0; i < best.left_count; ++i) best.left_box.grow(s[i].box);
  for (std::size_t i = n; i-- > best.left_count;) best.right_box.grow(s[i].box);
  return best;
}

void partition_object_split(const SortedRefs& refs, int axis, std::size_t left_count,
                            SortedRefs& left, SortedRefs& right) {
  const auto& split = refs.axis[axis];
  const std::size_t n = split.size();
  left.axis[axis].assign(split.begin(), split.begin() + std::ptrdiff_t(left_count));
  right.axis[axis].assign(split.begin() + std::ptrdiff_t(left_count), split.end());
  // Keys are unique, so a reference goes left exactly when its key precedes the first right one.
  const std::uint64_t pivot = centroid_key(split[left_count], axis);
  for (int a = 0; a < 3; ++a) {
    if (a == axis) continue;
    auto& l = left.axis[a];
    auto& r = right.axis[a];
    l.resize(left_count);
    r.resize(n - left_count);
    PrimRef* lp = l.data();
    PrimRef* rp = r.data();
    for (const PrimRef& ref : refs.axis[a]) {
      if (centroid_key(ref, axis) < pivot)
        *lp++ = ref;
      else
        *rp++ = ref;
    }
  }
}

void partition_object_split(SortedRefs&& refs, int axis, std::size_t left_count, SortedRefs& left,
                            SortedRefs& right, unsigned threads) {
  // The left child keeps the parent's arrays (pages already touched), compacted in place: a
  // left reference only ever moves to a lower index, so reading ahead of writing is safe.
  auto& split = refs.axis[axis];
  const std::size_t n = split.size();
  const std::uint64_t pivot = centroid_key(split[left_count], axis);
  reserve_huge(right.axis[axis], n - left_count);
  right.axis[axis].assign(split.begin() + std::ptrdiff_t(left_count), split.end());
  split.resize(left_count);
  parallel_for(2, threads, [&](std::size_t other) {  // the two other axes, apart
    const int a = (axis + 1 + int(other)) % 3;
    auto& v = refs.axis[a];
    auto& r = right.axis[a];
    reserve_huge(r, n - left_count);
    r.resize(n - left_count);
    PrimRef* lp = v.data();
    PrimRef* rp = r.data();
    for (const PrimRef& ref : v) {
      if (centroid_key(ref, axis) < pivot)
        *lp++ = ref;
      else
        *rp++ = ref;
    }
    v.resize(left_count);
  });
  left = std::move(refs);
}

}  // namespace kiln
