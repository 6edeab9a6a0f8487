// Object splits of the SBVH builder on presorted per-axis arrays.
#include <algorithm>
#include <cstddef>
#include <utility>
#include <vector>

#include "bvh_build_simd.hpp"
#include "bvh_splits.hpp"
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

// LSD radix sort of unique 64-bit keys, 11 bits a pass, skipping the passes whose digit is the
// same for every key (the high bits of the primitive ids, mostly): the order std::sort gives.
void radix_sort(std::vector<KeyIndex>& keys) {
  constexpr int kBits = 11, kPasses = 6;  // 66 bits
  constexpr std::size_t kBuckets = std::size_t(1) << kBits;
  std::vector<std::uint32_t> count(kPasses * kBuckets, 0);
  for (const KeyIndex& k : keys)
    for (int p = 0; p < kPasses; ++p)
      ++count[p * kBuckets + ((k.key >> (p * kBits)) & (kBuckets - 1))];
  std::vector<KeyIndex> tmp(keys.size());
  for (int p = 0; p < kPasses; ++p) {
    std::uint32_t* c = count.data() + p * kBuckets;
    if (std::any_of(c, c + kBuckets, [&](std::uint32_t n) { return n == keys.size(); })) continue;
    std::uint32_t sum = 0;
    for (std::size_t b = 0; b < kBuckets; ++b) sum += std::exchange(c[b], sum);
    for (const KeyIndex& k : keys) tmp[c[(k.key >> (p * kBits)) & (kBuckets - 1)]++] = k;
    keys.swap(tmp);
  }
}

constexpr std::size_t kRadixSort = 2048;  // radix sort from this many references, std::sort below

}  // namespace

void sort_by_centroid(std::span<const PrimRef> refs, int axis, std::vector<PrimRef>& out) {
  // Sorting 12-byte keys, then gathering once, costs a fraction of sorting 28-byte references.
  std::vector<KeyIndex> keys(refs.size());
  for (std::size_t i = 0; i < refs.size(); ++i)
    keys[i] = {centroid_key(refs[i], axis), std::uint32_t(i)};
  if (keys.size() >= kRadixSort)
    radix_sort(keys);
  else
    std::sort(keys.begin(), keys.end());
  out.resize(refs.size());
  for (std::size_t i = 0; i < refs.size(); ++i) out[i] = refs[keys[i].index];
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
  right.axis[axis].assign(split.begin() + std::ptrdiff_t(left_count), split.end());
  split.resize(left_count);
  parallel_for(2, threads, [&](std::size_t other) {  // the two other axes, apart
    const int a = (axis + 1 + int(other)) % 3;
    auto& v = refs.axis[a];
    auto& r = right.axis[a];
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
