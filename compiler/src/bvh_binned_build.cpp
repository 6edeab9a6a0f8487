// Binned SAH BVH (Wald 2007) built in place: one reference array, partitioned in place node by
// node (no per-node copies), nodes emitted straight into the depth-first layout. Large nodes
// near the root bin in parallel chunks (horizontal); below, subtrees run as tasks (vertical).
// Peak memory is the references (28 B per triangle) plus the nodes; the old recursive builder
// copied reference vectors per node and kept a pointer tree beside the flat one.
#include <algorithm>
#include <array>
#include <limits>
#include <optional>
#include <span>
#include <stdexcept>
#include <vector>

#include "bvh_subtree.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln {

namespace {

constexpr std::size_t kParallelSubtree = 16384;     // fork subtrees at least this large
constexpr std::size_t kParallelBinning = 1u << 18;  // bin in chunks above this many references
constexpr std::size_t kBinChunk = 1u << 16;

using format::Box3f;

/// k bins on each axis, axis-major. Sized per use (--bvh-bins may be up to 1024) and reused
/// per thread: initialising a large fixed array per node would cost more than binning.
struct Bins {
  std::uint32_t k = 0;
  std::vector<Box3f> box;
  std::vector<std::uint32_t> count;
  void reset(std::uint32_t bins) {
    k = bins;
    box.assign(3 * std::size_t(k), Box3f{});
    count.assign(3 * std::size_t(k), 0);
  }
  void merge(const Bins& o) {
    for (std::size_t i = 0; i < box.size(); ++i) box[i].grow(o.box[i]), count[i] += o.count[i];
  }
};

/// The mapping from a centroid to its bin on one axis; the same arithmetic bins and partitions,
/// so every reference lands on the side it was counted on.
struct BinMap {
  float origin[3], scale[3];
  std::uint32_t k;
  std::uint32_t bin(const PrimRef& r, int axis) const {
    const float c = r.box.centroid(axis);
    return std::min(k - 1, std::uint32_t(std::max(0.0f, (c - origin[axis]) * scale[axis])));
  }
};

struct Split {
  float cost = std::numeric_limits<float>::infinity();
  int axis = -1;
  std::uint32_t bin = 0;
  std::size_t left_count = 0;
  Box3f left_box, right_box;
};

struct Context {
  std::span<PrimRef> refs;
  const BvhBuildOptions& o;
  unsigned parallel_depth;
};

void bin_range(std::span<const PrimRef> refs, const BinMap& map, Bins& bins) {
  for (const PrimRef& r : refs)
    for (int a = 0; a < 3; ++a) {
      const std::uint32_t b = map.bin(r, a);
      bins.box[a * map.k + b].grow(r.box);
      bins.count[a * map.k + b] += 1;
    }
}

// Bins in fixed chunks merged in chunk order: the same bins on any thread count (box growth is
// min/max, exact in any order; counts are integers).
const Bins& bin_all(std::span<const PrimRef> refs, const BinMap& map, unsigned threads) {
  thread_local Bins bins;
  bins.reset(map.k);
  if (refs.size() < kParallelBinning) {
    bin_range(refs, map, bins);
    return bins;
  }
  const std::size_t chunks = (refs.size() + kBinChunk - 1) / kBinChunk;
  std::vector<Bins> partial(chunks);
  parallel_for(chunks, threads, [&](std::size_t c) {
    const std::size_t begin = c * kBinChunk;
    partial[c].reset(map.k);
    bin_range(refs.subspan(begin, std::min(kBinChunk, refs.size() - begin)), map, partial[c]);
  });
  for (const Bins& p : partial) bins.merge(p);
  return bins;
}

Split best_split(const Bins& bins, const BinMap& map, std::size_t n, float node_area,
                 const BvhBuildOptions& o) {
  Split best;
  thread_local std::vector<Box3f> right_box;
  right_box.resize(map.k);
  for (int a = 0; a < 3; ++a) {
    if (!(map.scale[a] > 0.0f)) continue;
    Box3f acc;
    for (std::uint32_t b = map.k; b-- > 1;) acc.grow(bins.box[a * map.k + b]), right_box[b] = acc;
    Box3f left;
    std::size_t left_count = 0;
    for (std::uint32_t b = 0; b + 1 < map.k; ++b) {
      // After an empty bin the split is the previous one at the same cost, which the strict
      // comparison below would not take: skip it (small nodes leave most bins empty).
      if (bins.count[a * map.k + b] == 0) continue;
      left.grow(bins.box[a * map.k + b]);
      left_count += bins.count[a * map.k + b];
      if (left_count == n) break;
      const float cost =
          o.traversal_cost + o.intersection_cost *
                                 (left.half_area() * float(left_count) +
                                  right_box[b + 1].half_area() * float(n - left_count)) /
                                 node_area;
      if (cost < best.cost) best = {cost, a, b, left_count, left, right_box[b + 1]};
    }
  }
  return best;
}

format::Float3 centroid(const PrimRef& r) {
  return {r.box.centroid(0), r.box.centroid(1), r.box.centroid(2)};
}

Box3f centroid_bounds(std::span<const PrimRef> refs) {
  Box3f c;
  for (const PrimRef& r : refs) c.grow(centroid(r));
  return c;
}

// Hoare partition by the split's bin: deterministic, in place, no buffer. Each reference is
// looked at once where it settles, which also gives each side's centroid bounds (the children's
// bin maps) without another pass. Returns the middle.
std::size_t partition_refs(std::span<PrimRef> refs, const BinMap& map, const Split& s,
                           Box3f& left_centroids, Box3f& right_centroids) {
  std::size_t i = 0, j = refs.size();
  while (true) {
    while (i < j && map.bin(refs[i], s.axis) <= s.bin) left_centroids.grow(centroid(refs[i++]));
    while (i < j && map.bin(refs[j - 1], s.axis) > s.bin) right_centroids.grow(centroid(refs[--j]));
    if (i >= j) return i;
    std::swap(refs[i], refs[j - 1]);
    left_centroids.grow(centroid(refs[i++]));
    right_centroids.grow(centroid(refs[--j]));
  }
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
};

void emit(const Context& ctx, const Task& t, std::vector<format::BvhNode>& nodes);

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
  const std::span<PrimRef> refs = ctx.refs.subspan(t.begin, n);
  const Box3f& c = t.centroids;
  BinMap map{};
  map.k = std::max<std::uint32_t>(o.bins, 2);
  for (int a = 0; a < 3; ++a) {
    const float extent = format::at(c.max, a) - format::at(c.min, a);
    map.origin[a] = format::at(c.min, a);
    map.scale[a] = extent > 0.0f ? float(map.k) / extent : 0.0f;
  }
  const float area = t.box.half_area();
  const unsigned threads = t.depth < ctx.parallel_depth ? 0u : 1u;
  const Split s = area > 0.0f ? best_split(bin_all(refs, map, threads), map, n, area, o) : Split{};
  if (s.axis < 0) {  // all centroids coincide (or a flat box): halve the list when too long
    if (n <= o.max_leaf_size) return std::nullopt;
    const std::size_t mid = t.begin + n / 2;
    Box3f l, r, lc, rc;
    for (std::size_t i = t.begin; i < mid; ++i)
      l.grow(ctx.refs[i].box), lc.grow(centroid(ctx.refs[i]));
    for (std::size_t i = mid; i < t.end; ++i)
      r.grow(ctx.refs[i].box), rc.grow(centroid(ctx.refs[i]));
    axis = 0;
    return std::pair{Task{t.begin, mid, l, lc, t.depth + 1}, Task{mid, t.end, r, rc, t.depth + 1}};
  }
  if (s.cost >= o.intersection_cost * float(n) && n <= o.max_leaf_size) return std::nullopt;
  Box3f lc, rc;
  const std::size_t mid = t.begin + partition_refs(refs, map, s, lc, rc);
  axis = s.axis;
  return std::pair{Task{t.begin, mid, s.left_box, lc, t.depth + 1},
                   Task{mid, t.end, s.right_box, rc, t.depth + 1}};
}

void emit(const Context& ctx, const Task& t, std::vector<format::BvhNode>& nodes) {
  const std::size_t index = nodes.size();
  nodes.push_back(leaf_node(t.box, t.begin, t.end - t.begin));
  int axis = 0;
  const auto children = split_task(ctx, t, axis);
  if (!children) return;
  const auto& [left, right] = *children;
  const bool fork = t.depth < ctx.parallel_depth && left.end - left.begin >= kParallelSubtree &&
                    right.end - right.begin >= kParallelSubtree;
  emit_bvh_children(fork, left, right, index, nodes,
                    [&](const Task& child, auto& out) { emit(ctx, child, out); });
  nodes[index].axis = std::uint8_t(axis);
}

}  // namespace

std::vector<format::BvhNode> build_binned_nodes(std::vector<PrimRef>& refs,
                                                const BvhBuildOptions& options) {
  Box3f root;
  for (const PrimRef& r : refs) root.grow(r.box);
  const Context ctx{refs, options, fork_depth(options.threads)};
  std::vector<format::BvhNode> nodes;
  emit(ctx, {0, refs.size(), root, centroid_bounds(refs), 0}, nodes);
  return nodes;
}

}  // namespace kiln
