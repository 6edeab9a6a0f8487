// Binned SAH BVH (Wald 2007) built in place: one reference array, partitioned in place node by
// node (no per-node copies), nodes emitted straight into the depth-first layout. Large nodes
// near the root bin in parallel chunks (horizontal); below, subtrees run as tasks (vertical).
// References are 32-byte records of two aligned vectors (bvh_build_simd.hpp): one SSE2
// computation gives a reference's centroid and its bin on all three axes, and a bin's box grows
// by two vector min/max, as in Embree's binning. A node of n references bins into
// min(bins, 4 + n/20) bins (object_bin_count, Embree's count), so the small nodes that make up
// most of the tree bin and sweep a few, all three axes at once. Every float operation is the one
// the scalar builder did, so the trees (splits, boxes, SAH costs) are the scalar builder's; only
// the order of references inside a leaf follows the branchless partition (and with it which of -0
// and +0 a bound keeps where both occur). Peak memory: the references (32 B each) and the nodes.
#include "bvh_binned_build.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <limits>
#include <optional>
#include <span>
#include <stdexcept>
#include <vector>

#include "bvh_splits.hpp"
#include "bvh_subtree.hpp"
#include "huge_pages.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln {

namespace {

constexpr std::size_t kParallelSubtree = 4096;      // fork subtrees at least this large
constexpr std::size_t kParallelBinning = 1u << 16;  // bin in chunks above this many references
constexpr std::size_t kBinChunk = 1u << 14;
constexpr std::uint32_t kMaxBins = 1024;     // as --bvh-bins allows
constexpr std::uint32_t kMaxLeafPacket = 8;  // split_packet's arrays

using bvh_simd::BuildRef;
using bvh_simd::V4;
using bvh_simd::VBox;
using format::Box3f;

/// k bins on each axis, axis-major. Sized per use (--bvh-bins may be up to 1024) and reused per
/// thread: between uses every bin is empty, so no reference branches on whether its bin is new
/// (growing an empty box gives the reference's box exactly). A bin's count is the fourth lane
/// of its upper corner, as an integer: a reference's upper corner has +0 there, which vmax
/// leaves to the count below 2^31 (as a float the count is +0, a positive denormal or a
/// positive normal, never less than +0), so one vector max and one integer add update box and
/// count (three loads and stores per axis fewer than a count array of its own; the binning is
/// bound by loads and stores). Readers take boxes with that lane cleared (`box_at`).
/// Up to 64 bins (a node's k is min(bins, 4 + n / 20)), the sweep reads and empties all 3k. Above
/// that, a bit per bin says it is occupied: `clear` empties and the sweep visits only those.
struct Bins {
  std::uint32_t k = 0, words = 0;  // words: 64-bit mask words per axis
  std::vector<VBox> box;           // upper corners' fourth lane: the count
  std::vector<std::uint64_t> used;
  static VBox empty() {
    constexpr float inf = std::numeric_limits<float>::infinity();
    return {bvh_simd::splat(inf), bvh_simd::set(-inf, -inf, -inf, 0.0f)};
  }
  void reset(std::uint32_t bins) {
    if (k == bins) return;  // already empty
    k = bins, words = (k + 63) / 64;
    box.assign(3 * std::size_t(k), empty());
    used.assign(3 * std::size_t(words), 0);
  }
  void clear() {
    if (k <= 64) {  // no occupancy bits (bin_range_64): all of them
      std::fill_n(box.begin(), 3 * std::size_t(k), empty());
      return;
    }
    for (int a = 0; a < 3; ++a)
      for_each(a, [&](std::uint32_t b) { box[std::size_t(a) * k + b] = empty(); });
    std::fill(used.begin(), used.end(), 0);
  }
  // Bin i's box (fourth lanes as a reference's) and its count.
  VBox box_at(std::size_t i) const { return {box[i].lo, bvh_simd::xyz(box[i].hi)}; }
  std::uint32_t count_at(std::size_t i) const { return bvh_simd::lane3_bits(box[i].hi); }
  // One reference (corners `lo`, `hi` with fourth lanes 0) into bin i.
  void grow(std::size_t i, V4 lo, V4 hi) {
    box[i].lo = bvh_simd::vmin(lo, box[i].lo);
    box[i].hi = bvh_simd::add_lane3(bvh_simd::vmax(hi, box[i].hi), 1);
  }
  void add(int a, std::uint32_t b, V4 lo, V4 hi) {
    used[std::size_t(a) * words + b / 64] |= std::uint64_t(1) << (b % 64);
    grow(std::size_t(a) * k + b, lo, hi);
  }
  // Calls f(b) for each occupied bin of axis a, in increasing order.
  template <class F>
  void for_each(int a, F&& f) const {
    for (std::uint32_t w = 0; w < words; ++w)
      for (std::uint64_t bits = used[std::size_t(a) * words + w]; bits; bits &= bits - 1)
        f(w * 64 + std::uint32_t(std::countr_zero(bits)));
  }
  // In chunk order: the same boxes as binning the chunks' references one after another.
  void merge(const Bins& o) {
    for (std::size_t i = 0; i < 3 * std::size_t(k); ++i)
      box[i].lo = bvh_simd::vmin(o.box[i].lo, box[i].lo),
      box[i].hi = bvh_simd::vmax_add_lane3(o.box[i].hi, box[i].hi);
    if (k > 64)
      for (std::size_t w = 0; w < used.size(); ++w) used[w] |= o.used[w];
  }
};

/// The mapping from a centroid to its bin on each axis, min(k - 1, trunc(max(0, (c - origin) x
/// scale))) per lane; the same arithmetic bins and partitions, so every reference lands on the
/// side it was counted on.
struct BinMap {
  V4 origin, scale, last;
  float axis_scale[3];
  std::uint32_t k;
  BinMap(const Box3f& centroids, std::uint32_t bins) : k(bins) {
    for (int a = 0; a < 3; ++a) {
      const float extent = format::at(centroids.max, a) - format::at(centroids.min, a);
      axis_scale[a] = extent > 0.0f ? float(k) / extent : 0.0f;
    }
    origin = bvh_simd::set(centroids.min.x, centroids.min.y, centroids.min.z, 0.0f);
    scale = bvh_simd::set(axis_scale[0], axis_scale[1], axis_scale[2], 0.0f);
    last = bvh_simd::splat(float(k - 1));
  }
  // Bins on the three axes (lane 3 is 0) of a reference whose centroid is `c`.
  // The bins before truncation: (c - origin) x scale clamped to [0, k - 1]. vmax(x, 0) is
  // x > 0 ? x : 0 (NaN to 0, as std::max(0.0f, x)).
  V4 clamped(V4 c) const {
    return bvh_simd::vmin(bvh_simd::vmax((c - origin) * scale, bvh_simd::splat(0.0f)), last);
  }
  void bins(V4 c, std::int32_t* out) const { bvh_simd::truncate(clamped(c), out); }
};

struct Split {
  float cost = std::numeric_limits<float>::infinity();
  // The weighted area sum that gave `cost` (cost = traversal + intersection x sum / area, which
  // never decreases as the sum grows): a candidate with no smaller sum cannot cost less, so
  // the sweep divides only for candidates below it.
  float sum = std::numeric_limits<float>::infinity();
  int axis = -1;
  std::uint32_t bin = 0;
  std::size_t left_count = 0;
  VBox left_box, right_box;
};

// The statistics of the final node array (flat_bvh_statistics'), counted as it fills: the thread
// that emits into it counts each node once decided (a leaf, or interior before its children),
// and a subtree built apart once appended, so every node in index order (the SAH cost is a sum
// of doubles in that order); the nodes are counted where they are written or just after, not
// streamed again. The depth from the leaves' tasks, on whichever thread emits them.
struct NodeTally {
  // Read by every thread for every node: apart from the lines the counting thread writes.
  const std::vector<format::BvhNode>* nodes = nullptr;  // the final array
  double root_area = 0;
  alignas(64) std::atomic<std::uint32_t> max_depth{0};  // written only when it grows
  alignas(64) std::size_t counted = 0;                  // nodes[0, counted) are counted
  BvhStatistics stats;

  void count(const format::BvhNode& n, bool leaf, const BvhBuildOptions& o) {
    stats.sah_cost += bvh_sah_term(n, leaf, root_area, o);
    counted += 1;
    if (!leaf) return;
    stats.leaf_count += 1;
    stats.reference_count += n.count;
    stats.max_leaf_size = std::max<std::uint32_t>(stats.max_leaf_size, n.count);
  }
  // The nodes appended since the last count (a subtree built apart).
  void catch_up(const std::vector<format::BvhNode>& all, const BvhBuildOptions& o) {
    for (std::size_t i = counted; i < all.size(); ++i) count(all[i], all[i].count != 0, o);
  }
  void leaf_depth(std::uint32_t depth) {
    std::uint32_t m = max_depth.load(std::memory_order_relaxed);
    while (depth > m && !max_depth.compare_exchange_weak(m, depth, std::memory_order_relaxed)) {
    }
  }
};

struct Context {
  std::span<BuildRef> refs;
  const BvhBuildOptions& o;
  WorkerSlots& slots;      // threads free for a subtree or a parallel binning
  PendingRights& pending;  // right children a thread with nothing to do may build
  NodeTally& tally;
  std::span<std::uint32_t> prim_ids;  // empty, or filled leaf by leaf
};

void bin_range(std::span<const BuildRef> refs, const BinMap& map, Bins& bins) {
  for (const BuildRef& r : refs) {
    alignas(16) std::int32_t b[4];
    map.bins(bvh_simd::centroid(r), b);
    const V4 lo = bvh_simd::lower(r), hi = bvh_simd::upper(r);
    for (int a = 0; a < 3; ++a) bins.add(a, std::uint32_t(b[a]), lo, hi);
  }
}

// k <= 64: no occupancy bits (the sweep reads all bins); the bins start empty, so each
// reference grows its three bins without a branch. The two halves of the list interleaved:
// neighbours in the list mostly share bins, and each update of a bin waits for the one before
// (its load for that store), so the halves' updates overlap where one list's would queue
// (binary build -6 %, dragon_871k). Exact in any order (min, max and integer counts; only which
// of -0 and +0 a bound keeps where both occur follows the order), and the order is fixed.
void bin_range_64(std::span<const BuildRef> refs, const BinMap& map, Bins& bins) {
  const std::size_t k = map.k;
  const auto one = [&](const BuildRef& r) {
    alignas(16) std::int32_t b[4];
    map.bins(bvh_simd::centroid(r), b);
    const V4 lo = bvh_simd::lower(r), hi = bvh_simd::upper(r);
    for (int a = 0; a < 3; ++a) bins.grow(std::size_t(a) * k + std::size_t(b[a]), lo, hi);
  };
  const std::size_t half = refs.size() / 2, rest = refs.size() - half;
  for (std::size_t i = 0; i < half; ++i) one(refs[i]), one(refs[rest + i]);
  if (rest > half) one(refs[half]);
}

// Bins `refs` into `bins` (empty, or sized now).
void bin_into(std::span<const BuildRef> refs, const BinMap& map, Bins& bins) {
  bins.reset(map.k);
  if (map.k > 64) return bin_range(refs, map, bins);
  bin_range_64(refs, map, bins);
}

// Bins in fixed chunks merged in chunk order: the same bins on any thread count (box growth is
// min/max, exact in any order; counts are integers).
Bins& bin_all(std::span<const BuildRef> refs, const BinMap& map, unsigned threads) {
  thread_local Bins bins;
  if (refs.size() < kParallelBinning) {
    bin_into(refs, map, bins);
    return bins;
  }
  bins.reset(map.k);
  const std::size_t chunks = (refs.size() + kBinChunk - 1) / kBinChunk;
  std::vector<Bins> partial(chunks);
  parallel_for(chunks, threads, [&](std::size_t c) {
    const std::size_t begin = c * kBinChunk;
    bin_into(refs.subspan(begin, std::min(kBinChunk, refs.size() - begin)), map, partial[c]);
  });
  for (const Bins& p : partial) bins.merge(p);
  return bins;
}

// The SAH sweep over one axis's occupied bins: a split after an empty bin is the previous one at
// the same cost, which the strict comparison would not take, so only occupied bins are
// candidates, and small nodes (most of them) cost their occupied bins, not k. Records the
// winner's cost, axis, bin and count; best_split grows its boxes after.
void sweep_axis(const Bins& bins, int a, std::size_t n, float node_area, const BvhBuildOptions& o,
                Split& best) {
  std::uint16_t used[kMaxBins];
  float right_area[kMaxBins];
  const std::size_t base = std::size_t(a) * bins.k;
  std::size_t m = 0;
  bins.for_each(a, [&](std::uint32_t b) { used[m++] = std::uint16_t(b); });
  if (m < 2) return;
  VBox acc;
  for (std::size_t j = m; j-- > 1;) {
    acc.grow(bins.box_at(base + used[j]));
    right_area[j] = bvh_simd::half_area(acc);
  }
  VBox left;
  std::size_t left_count = 0;
  for (std::size_t j = 0; j + 1 < m; ++j) {
    left.grow(bins.box_at(base + used[j]));
    left_count += bins.count_at(base + used[j]);
    const float sum =
        bvh_simd::half_area(left) * float(left_count) + right_area[j + 1] * float(n - left_count);
    if (!(sum < best.sum)) continue;
    const float cost = o.traversal_cost + o.intersection_cost * sum / node_area;
    if (cost < best.cost)
      best.cost = cost, best.sum = sum, best.axis = a, best.bin = used[j],
      best.left_count = left_count;
  }
}

// best_split for k <= 64 (every node at the default 32 bins) with the three axes side by side, a
// lane each: one pass down the bins keeps the half area of each axis's bins above every bin,
// one pass up takes every candidate of all three axes at once, with selects; the winner's boxes
// are regrown after, on its axis alone. Both passes run over all k bins: growing a box by an
// empty bin changes nothing, and a candidate after an empty bin costs what the one before it
// did, which the strict comparison does not take, so the winner is the first least cost in
// axis order, then bin order, as sweep_axis's; candidates with an empty side are masked. Loops
// of k - 1 steps (k is 4 below 20 references) instead of loops over each axis's occupied bins,
// whose data-dependent exits mispredicted: binary build -2 to -3 % (dragon_871k, Sponza).
Split best_split_lanes(const Bins& bins, const BinMap& map, std::size_t n, float node_area,
                       const BvhBuildOptions& o) {
  using namespace bvh_simd;
  const std::size_t k = bins.k;
  alignas(16) float above[64][4];  // above[b][a]: axis a's bins above b, half area
  VBox acc[3];
  for (std::size_t b = k; b-- > 1;) {
    for (int a = 0; a < 3; ++a) acc[a].grow(bins.box_at(std::size_t(a) * k + b));
    store(above[b - 1], half_areas(acc[0], acc[1], acc[2]));
  }
  const V4 enabled =
      lt(splat(0.0f), set(map.axis_scale[0], map.axis_scale[1], map.axis_scale[2], 0.0f));
  const V4 traversal = splat(o.traversal_cost), intersection = splat(o.intersection_cost);
  const V4 area = splat(node_area), zero = splat(0.0f);
  V4 best_cost = splat(std::numeric_limits<float>::infinity()), best_sum = best_cost;
  V4 best_bin = zero;
  VBox left[3];
  // The three axes' counts on the left, a lane each, as integers gathered from the bins' fourth
  // lanes (n < 2^31: float(n - lc[a]) is the conversion of an int32). The bins' boxes are grown
  // with their count lanes cleared: as floats most counts are denormals, which some CPUs subtract
  // (half_areas) only through a slow assist.
  V4 lc = splat_bits(0);
  const V4 all = splat_bits(std::uint32_t(n));
  for (std::size_t b = 0; b + 1 < k; ++b) {
    const VBox& x = bins.box[b];
    const VBox& y = bins.box[std::size_t(k) + b];
    const VBox& z = bins.box[2 * std::size_t(k) + b];
    lc = add_bits(lc, lanes3(x.hi, y.hi, z.hi));
    left[0].grow(x.lo, xyz(x.hi)), left[1].grow(y.lo, xyz(y.hi)), left[2].grow(z.lo, xyz(z.hi));
    const V4 lcount = bits_to_float(lc), rcount = bits_to_float(sub_bits(all, lc));
    const V4 sum = half_areas(left[0], left[1], left[2]) * lcount + load(above[b]) * rcount;
    const V4 cost = traversal + intersection * sum / area;
    const V4 take = enabled & lt(zero, lcount) & lt(zero, rcount) & lt(cost, best_cost);
    best_cost = blend(take, cost, best_cost), best_sum = blend(take, sum, best_sum);
    best_bin = blend(take, splat(float(b)), best_bin);
  }
  alignas(16) float c[4], s[4], w[4];
  store(c, best_cost), store(s, best_sum), store(w, best_bin);
  Split best;
  // The first axis of the least cost, without branches (which one wins is data-dependent).
  const float least = std::min(std::min(c[0], c[1]), c[2]);
  const int a = std::countr_zero(unsigned(mask_bits(le(best_cost, splat(least)))));
  if (least < best.cost)  // else no candidate (every axis masked)
    best.cost = c[a], best.sum = s[a], best.axis = a, best.bin = std::uint32_t(w[a]);
  if (best.axis >= 0) {  // the winner's boxes: the left side upwards, the right side downwards
    const std::size_t base = std::size_t(best.axis) * k;
    for (std::size_t b = 0; b <= best.bin; ++b)
      best.left_box.grow(bins.box_at(base + b)), best.left_count += bins.count_at(base + b);
    for (std::size_t b = k; b-- > best.bin + 1;) best.right_box.grow(bins.box_at(base + b));
  }
  return best;
}

Split best_split(Bins& bins, const BinMap& map, std::size_t n, float node_area,
                 const BvhBuildOptions& o) {
  if (bins.k <= 64) return best_split_lanes(bins, map, n, node_area, o);
  Split best;
  for (int a = 0; a < 3; ++a)
    if (map.axis_scale[a] > 0.0f) sweep_axis(bins, a, n, node_area, o, best);
  if (best.axis < 0) return best;
  // The winner's boxes, grown as the sweep grew them: the left side upwards, the right side
  // from the last bin down.
  const std::size_t base = std::size_t(best.axis) * bins.k;
  std::uint16_t right[kMaxBins];
  std::size_t m = 0;
  bins.for_each(best.axis, [&](std::uint32_t b) {
    if (b <= best.bin)
      best.left_box.grow(bins.box_at(base + b));
    else
      right[m++] = std::uint16_t(b);
  });
  while (m-- > 0) best.right_box.grow(bins.box_at(base + right[m]));
  return best;
}

VBox centroid_bounds(std::span<const BuildRef> refs) {
  VBox c;
  for (const BuildRef& r : refs) {
    const V4 p = bvh_simd::centroid(r);
    c.grow(p, p);
  }
  return c;
}

// Partition by the split's bin, in place and without a branch on the side (a mispredicted
// branch per reference cost more than the moves): every reference is swapped with the first one
// not known to go left, and that boundary advances when it went left (the cyclic Lomuto scheme
// of Edelkamp and Weiss's BlockQuicksort). Deterministic, no buffer. The children bound their
// centroids where they bin (split_task): growing both sides' bounds here took four selects and
// four min/max per reference, more than a child's plain pass, also on the largest nodes.
// Returns the middle.
std::size_t partition_refs(std::span<BuildRef> refs, const BinMap& map, const Split& s) {
  // trunc(x) <= bin exactly when x < bin + 1 (x in [0, k - 1], integers exact as floats): the
  // side comes from one compare, without storing the bins.
  const V4 limit = bvh_simd::splat(float(s.bin + 1));
  std::size_t l = 0;
  for (std::size_t i = 0; i < refs.size(); ++i) {
    // The swap in registers, as two vectors per reference (a 32-byte copy went through the
    // stack).
    const V4 lo = bvh_simd::load(refs[i].lo), hi = bvh_simd::load(refs[i].hi);
    const V4 c = (bvh_simd::xyz(lo) + hi) * bvh_simd::splat(0.5f);  // bvh_simd::centroid
    const bool left = (bvh_simd::less_mask(map.clamped(c), limit) >> s.axis) & 1;
    bvh_simd::store(refs[i].lo, bvh_simd::load(refs[l].lo));
    bvh_simd::store(refs[i].hi, bvh_simd::load(refs[l].hi));
    bvh_simd::store(refs[l].lo, lo);
    bvh_simd::store(refs[l].hi, hi);
    l += left;
  }
  return l;
}

// Pieces of the reference array, in index order: [begin, begin + size) each.
struct Segments {
  std::vector<std::size_t> begin, end_rank;  // end_rank: references in this piece and before
  void add(std::size_t b, std::size_t e) {
    if (e <= b) return;
    begin.push_back(b);
    end_rank.push_back((end_rank.empty() ? 0 : end_rank.back()) + (e - b));
  }
  // The index of the rank-th reference the pieces hold.
  std::size_t at(std::size_t rank, std::size_t& piece) const {
    while (end_rank[piece] <= rank) ++piece;
    return begin[piece] + rank - (piece ? end_rank[piece - 1] : 0);
  }
};

// partition_refs for large nodes, in fixed blocks: each block of kBinChunk references is
// partitioned on its own (its two streams stay in cache, where one partition of the whole node
// swaps across megabytes), then the right references before the middle swap with the left ones
// after it, the i-th with the i-th in index order. Same sides; only the order inside the
// children differs from partition_refs'. The blocks, and the swaps in fixed chunks, run on
// `threads` (the same bytes on any count).
std::size_t partition_blocks(std::span<BuildRef> refs, const BinMap& map, const Split& s,
                             unsigned threads) {
  const std::size_t n = refs.size(), blocks = (n + kBinChunk - 1) / kBinChunk;
  std::vector<std::size_t> lefts(blocks);
  parallel_for(blocks, threads, [&](std::size_t b) {
    const std::size_t begin = b * kBinChunk;
    lefts[b] = partition_refs(refs.subspan(begin, std::min(kBinChunk, n - begin)), map, s);
  });
  std::size_t mid = 0;
  for (std::size_t b = 0; b < blocks; ++b) mid += lefts[b];
  Segments right_before, left_after;  // misplaced: right ones before mid, left ones after
  for (std::size_t b = 0; b < blocks; ++b) {
    const std::size_t begin = b * kBinChunk, end = std::min(n, begin + kBinChunk);
    const std::size_t split = begin + lefts[b];
    right_before.add(split, std::min(end, mid));
    left_after.add(std::max(begin, mid), split);
  }
  const std::size_t misplaced = right_before.end_rank.empty() ? 0 : right_before.end_rank.back();
  // The i-th misplaced pairs swap in fixed chunks of i (each pair on its own, so on any threads).
  parallel_for((misplaced + kBinChunk - 1) / kBinChunk, threads, [&](std::size_t c) {
    std::size_t p = 0, q = 0;
    for (std::size_t i = c * kBinChunk; i < std::min(misplaced, (c + 1) * kBinChunk); ++i)
      std::swap(refs[right_before.at(i, p)], refs[left_after.at(i, q)]);
  });
  return mid;
}

format::BvhNode leaf_node(const Box3f& box, std::size_t begin, std::size_t count) {
  format::BvhNode node{};
  for (int a = 0; a < 3; ++a)
    node.min[a] = format::at(box.min, a), node.max[a] = format::at(box.max, a);
  node.offset = std::uint32_t(begin);
  node.count = std::uint16_t(count);
  return node;
}

struct Task {
  std::size_t begin, end;
  Box3f box, centroids;  // the references' boxes and centroids
  std::uint32_t depth;
  // false: `centroids` not computed yet (split_task bounds them where it bins: nodes of a packet
  // or less never need them).
  bool has_centroids = true;
};

void emit(const Context& ctx, const Task& t, std::vector<format::BvhNode>& nodes);

// The first axis on which the centroids spread (a bin map gives them bins 0 and k - 1), or -1.
int first_spread_axis(const Box3f& centroids) {
  for (int a = 0; a < 3; ++a)
    if (format::at(centroids.max, a) - format::at(centroids.min, a) > 0.0f) return a;
  return -1;
}

// split_task for two references whose centroids spread on `a`, without binning: on every axis
// where they spread they take bins 0 and k - 1, so the only candidate is one against the other,
// at the same cost on each axis (the same two areas summed), and the first such axis wins.
// Same cost, boxes and reference order as binning and partitioning gives.
std::optional<std::pair<Task, Task>> split_pair(const Context& ctx, const Task& t, int a,
                                                int& axis) {
  const auto& o = ctx.o;
  BuildRef* r = ctx.refs.data() + t.begin;
  alignas(16) float c[2][4];
  bvh_simd::store(c[0], bvh_simd::centroid(r[0]));
  bvh_simd::store(c[1], bvh_simd::centroid(r[1]));
  const int first = c[1][a] < c[0][a] ? 1 : 0;  // the one on the left
  const VBox l{bvh_simd::lower(r[first]), bvh_simd::upper(r[first])};
  const VBox rb{bvh_simd::lower(r[1 - first]), bvh_simd::upper(r[1 - first])};
  const float sum = bvh_simd::half_area(l) * 1.0f + bvh_simd::half_area(rb) * 1.0f;
  const float cost = o.traversal_cost + o.intersection_cost * sum / t.box.half_area();
  if (cost >= o.intersection_cost * 2.0f && 2 <= o.max_leaf_size) return std::nullopt;
  axis = a;
  if (first == 1) std::swap(r[0], r[1]), std::swap(c[0], c[1]);  // the partition's order
  const auto point = [](const float* c) { return Box3f{{c[0], c[1], c[2]}, {c[0], c[1], c[2]}}; };
  return std::pair{Task{t.begin, t.begin + 1, l.box(), point(c[0]), t.depth + 1},
                   Task{t.begin + 1, t.end, rb.box(), point(c[1]), t.depth + 1}};
}

// Whether a node of n references stays a leaf against its best split `s`: by the SAH with a
// test per reference, or (leaf_packet) with leaves priced per packet.
bool leaf_wins(const Split& s, std::size_t n, float area, const BvhBuildOptions& o) {
  if (o.leaf_packet == 0) return s.cost >= o.intersection_cost * float(n);
  return packet_leaf_wins(o, n, area, bvh_simd::half_area(s.left_box), s.left_count,
                          bvh_simd::half_area(s.right_box));
}

// leaf_packet: a node of at most one packet (n <= leaf_packet <= 8) stays a leaf unless two
// packets under smaller boxes save area: of every way to part its references in two (the
// subsets holding the first one, in increasing bit order), the least sum of the two sides'
// areas splits it when below the node's area (the first such subset on ties). Exact and
// without bins or sorting, so the small nodes the wide layout ends in cost a few box unions.
std::optional<std::pair<Task, Task>> split_packet(const Context& ctx, const Task& t, int& axis) {
  const auto n = std::uint32_t(t.end - t.begin);
  BuildRef* r = ctx.refs.data() + t.begin;
  const std::uint32_t full = (1u << n) - 1;
  V4 lo[1u << kMaxLeafPacket], hi[1u << kMaxLeafPacket];  // subset m's box (uninitialised)
  float area[1u << kMaxLeafPacket];
  const auto box = [&](std::uint32_t m) { return VBox{lo[m], hi[m]}; };
  for (std::uint32_t m = 1; m <= full; ++m) {
    const int low = std::countr_zero(m);
    VBox b;
    if (m & (m - 1)) b = box(m & (m - 1));
    b.grow(bvh_simd::lower(r[low]), bvh_simd::upper(r[low]));
    lo[m] = b.lo, hi[m] = b.hi, area[m] = bvh_simd::half_area(b);
  }
  float best = t.box.half_area();
  std::uint32_t best_mask = 0;
  for (std::uint32_t m = 1; m < full; m += 2) {  // odd: holds the first reference
    const float sum = area[m] + area[full ^ m];
    if (sum < best) best = sum, best_mask = m;
  }
  if (best_mask == 0) return std::nullopt;
  BuildRef parted[kMaxLeafPacket];
  std::uint32_t left = 0, right = std::popcount(best_mask);
  for (std::uint32_t i = 0; i < n; ++i) parted[(best_mask >> i & 1) ? left++ : right++] = r[i];
  std::copy(parted, parted + n, r);
  // The axis on which the two sides' boxes lie furthest apart (their centres), for the node.
  const std::uint32_t other = full ^ best_mask;
  const V4 gap = (lo[best_mask] + hi[best_mask]) - (lo[other] + hi[other]);
  alignas(16) float g[4];
  bvh_simd::store(g, gap);
  axis = 0;
  for (int a = 1; a < 3; ++a)
    if (std::abs(g[a]) > std::abs(g[axis])) axis = a;
  const auto side = [&](std::size_t begin, std::size_t end, const VBox& b) {
    return Task{begin, end, b.box(), {}, t.depth + 1, false};
  };
  return std::pair{side(t.begin, t.begin + left, box(best_mask)),
                   side(t.begin + left, t.end, box(other))};
}

// Splits [begin, end) by the SAH (or in half when every centroid coincides) and returns the two
// child tasks, or nothing when the node should be a leaf.
std::optional<std::pair<Task, Task>> split_task(const Context& ctx, const Task& t, int& axis) {
  const auto& o = ctx.o;
  const std::size_t n = t.end - t.begin;
  const bool must_stop = t.depth + 1 >= format::kBvhMaxDepth;
  if (n <= 1 || must_stop) {
    if (n > format::kBvhMaxLeafSize)
      throw std::runtime_error("BVH: " + std::to_string(n) + " references left at maximum depth");
    return std::nullopt;
  }
  if (n <= o.leaf_packet) return split_packet(ctx, t, axis);
  const std::span<BuildRef> refs = ctx.refs.subspan(t.begin, n);
  // Bounded here, from the references in their place, when the partition did not: min and max
  // in another order can keep the other of -0 and +0, which maps to the same bins.
  const Box3f centroids = t.has_centroids ? t.centroids : centroid_bounds(refs).box();
  const float area = t.box.half_area();
  if (n == 2 && area > 0.0f)
    if (const int a = first_spread_axis(centroids); a >= 0) return split_pair(ctx, t, a, axis);
  const BinMap map(centroids, object_bin_count(n, o.bins));
  Split s;
  if (area > 0.0f) {
    const unsigned extra = n >= kParallelBinning ? ctx.slots.take_all() : 0u;
    Bins& bins = bin_all(refs, map, 1 + extra);
    if (extra > 0) ctx.slots.give(extra);  // no atomic per node when nothing was taken
    s = best_split(bins, map, n, area, o);
    bins.clear();
  }
  if (s.axis < 0) {  // all centroids coincide (or a flat box): halve the list when too long
    if (n <= o.max_leaf_size) return std::nullopt;
    const std::size_t mid = t.begin + n / 2;
    VBox l, r;
    for (std::size_t i = t.begin; i < mid; ++i)
      l.grow(bvh_simd::lower(ctx.refs[i]), bvh_simd::upper(ctx.refs[i]));
    for (std::size_t i = mid; i < t.end; ++i)
      r.grow(bvh_simd::lower(ctx.refs[i]), bvh_simd::upper(ctx.refs[i]));
    const Box3f lc = centroid_bounds(ctx.refs.subspan(t.begin, mid - t.begin)).box();
    const Box3f rc = centroid_bounds(ctx.refs.subspan(mid, t.end - mid)).box();
    axis = 0;
    return std::pair{Task{t.begin, mid, l.box(), lc, t.depth + 1},
                     Task{mid, t.end, r.box(), rc, t.depth + 1}};
  }
  if (n <= o.max_leaf_size && leaf_wins(s, n, area, o)) return std::nullopt;
  std::size_t mid = t.begin;
  if (n >= kParallelBinning) {
    const unsigned extra = ctx.slots.take_all();
    mid += partition_blocks(refs, map, s, 1 + extra);
    if (extra > 0) ctx.slots.give(extra);
  } else {
    mid += partition_refs(refs, map, s);
  }
  axis = s.axis;
  // The children bound their centroids where they bin (none do at a packet or less).
  return std::pair{Task{t.begin, mid, s.left_box.box(), {}, t.depth + 1, false},
                   Task{mid, t.end, s.right_box.box(), {}, t.depth + 1, false}};
}

void emit(const Context& ctx, const Task& t, std::vector<format::BvhNode>& nodes) {
  const std::size_t index = nodes.size();
  nodes.push_back(leaf_node(t.box, t.begin, t.end - t.begin));
  int axis = 0;
  const auto children = split_task(ctx, t, axis);
  NodeTally* const tally = &nodes == ctx.tally.nodes ? &ctx.tally : nullptr;
  if (tally) tally->count(nodes[index], !children, ctx.o);
  if (!children) {
    if (ctx.tally.nodes) ctx.tally.leaf_depth(t.depth + 1);  // counting (the root's depth is 1)
    if (!ctx.prim_ids.empty())
      for (std::size_t i = t.begin; i < t.end; ++i) ctx.prim_ids[i] = ctx.refs[i].prim();
    return;
  }
  const auto& [left, right] = *children;
  const std::size_t right_size = right.end - right.begin;
  const bool may_fork = left.end - left.begin >= kParallelSubtree && right_size >= kParallelSubtree;
  // A subtree built apart is counted beside its append, from its own nodes: the nodes before it
  // are all counted here, so the order (and the SAH sum) is the one catch_up would give.
  const CountApart count_apart = tally && may_fork
                                     ? CountApart([&](const std::vector<format::BvhNode>& sub) {
                                         for (const format::BvhNode& n : sub)
                                           tally->count(n, n.count != 0, ctx.o);
                                       })
                                     : CountApart();
  emit_bvh_children_on_demand(
      ctx.slots, may_fork, left, right, right_size + right_size / 4 + 1, index, nodes,
      [&](const Task& child, auto& out) { emit(ctx, child, out); }, &ctx.pending, count_apart);
  nodes[index].axis = std::uint8_t(axis);
  if (tally) tally->catch_up(nodes, ctx.o);  // a right subtree built apart and appended
}

}  // namespace

std::span<BuildRef> triangle_build_refs(const Scene& scene, unsigned threads,
                                        UninitializedVector<std::byte>& block,
                                        std::size_t reserve_bytes) {
  const std::size_t bytes = scene.triangles.size() * sizeof(BuildRef);
  block = {};
  reserve_huge(block, std::max(bytes, reserve_bytes));
  block.resize(bytes);
  // operator new's blocks are aligned for BuildRef's vectors (16 bytes).
  static_assert(__STDCPP_DEFAULT_NEW_ALIGNMENT__ >= alignof(BuildRef));
  const std::span<BuildRef> refs(reinterpret_cast<BuildRef*>(block.data()), scene.triangles.size());
  parallel_for_batched(refs.size(), 65536, threads, [&](std::size_t i) {
    Box3f box;
    for (const auto v : scene.triangles[i].v) box.grow(scene.positions[v]);
    refs[i] = BuildRef::make(box, std::uint32_t(i));
  });
  return refs;
}

std::vector<format::BvhNode> build_binned_nodes(std::span<BuildRef> refs,
                                                const BvhBuildOptions& options,
                                                BvhStatistics* counts,
                                                std::span<std::uint32_t> prim_ids) {
  if (!prim_ids.empty() && prim_ids.size() != refs.size())
    throw std::invalid_argument("BVH: one primitive id per reference");
  if (refs.size() >= std::size_t(1) << 31)  // a bin's count is 31 bits (Bins)
    throw std::invalid_argument("BVH: at most 2^31 - 1 references for the binned build");
  if (options.bins > kMaxBins)
    throw std::invalid_argument("BVH: at most " + std::to_string(kMaxBins) + " bins");
  if (options.leaf_packet > kMaxLeafPacket)
    throw std::invalid_argument("BVH: packets of at most " + std::to_string(kMaxLeafPacket));
  // The root's box and centroid bounds in one pass over fixed chunks (in parallel), merged in
  // chunk order: the bounds one pass in order gives.
  const std::size_t chunks = (refs.size() + kBinChunk - 1) / kBinChunk;
  std::vector<VBox> box(std::max<std::size_t>(chunks, 1)), centroids(box.size());
  parallel_for(chunks, options.threads, [&](std::size_t c) {
    // Grown in registers, stored once: through memory, neighbouring chunks' boxes share cache
    // lines that both threads would write for every reference (at two threads this pass took
    // five times its one-thread share of the samples).
    VBox b, cb;
    for (const BuildRef& r :
         refs.subspan(c * kBinChunk, std::min(kBinChunk, refs.size() - c * kBinChunk))) {
      b.grow(bvh_simd::lower(r), bvh_simd::upper(r));
      const V4 p = bvh_simd::centroid(r);
      cb.grow(p, p);
    }
    box[c] = b, centroids[c] = cb;
  });
  for (std::size_t c = 1; c < chunks; ++c) box[0].grow(box[c]), centroids[0].grow(centroids[c]);
  WorkerSlots slots(resolve_thread_count(options.threads));
  PendingRights pending;
  std::vector<format::BvhNode> nodes;
  NodeTally tally;
  if (counts) {
    tally.nodes = &nodes;
    tally.root_area = bvh_node_half_area(leaf_node(box[0].box(), 0, refs.size()));  // nodes[0]'s
  }
  const Context ctx{refs, options, slots, pending, tally, prim_ids};
  // SAH trees here have 1.0-1.15 nodes per reference: no regrowth (and copy) of the array.
  reserve_huge(nodes, refs.size() + refs.size() / 4 + 1);
  emit(ctx, {0, refs.size(), box[0].box(), centroids[0].box(), 0}, nodes);
  if (counts) {
    if (tally.counted != nodes.size())
      throw std::logic_error("BVH: the binned build's statistics missed a node");
    *counts = tally.stats;
    counts->node_count = nodes.size();
    counts->max_depth = tally.max_depth.load();
  }
  return nodes;
}

std::vector<format::BvhNode> build_binned_nodes(std::vector<PrimRef>& refs,
                                                const BvhBuildOptions& options) {
  std::vector<BuildRef> build(refs.size());
  for (std::size_t i = 0; i < refs.size(); ++i)
    build[i] = BuildRef::make(refs[i].box, refs[i].prim);
  std::vector<format::BvhNode> nodes = build_binned_nodes(std::span<BuildRef>(build), options);
  for (std::size_t i = 0; i < refs.size(); ++i) refs[i] = {build[i].box(), build[i].prim()};
  return nodes;
}

}  // namespace kiln
