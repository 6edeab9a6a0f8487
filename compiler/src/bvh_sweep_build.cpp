// Full-sweep SAH BVH on presorted arrays: the references are sorted by centroid once per axis
// (ties by primitive id), and each split partitions the three arrays stably by side, so every
// node sees its references in sorted order on every axis without sorting again: O(n log n) for
// the whole build instead of three sorts per node. The trees are the ones the per-node sorting
// builder made (same costs, same ties, same leaf order).
#include <algorithm>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <vector>

#include "bvh_subtree.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln {

namespace {

constexpr std::size_t kParallelSubtree = 16384;

using format::Box3f;

struct Context {
  std::span<const PrimRef> refs;       // by primitive id
  std::vector<std::uint32_t>* sorted;  // [3]: primitive ids by centroid on each axis
  std::vector<std::uint8_t>& goes_left;
  std::span<std::uint32_t> order;  // out: the leaf order of primitive ids
  const BvhBuildOptions& o;
  unsigned parallel_depth;
};

struct Task {
  std::size_t begin, end;
  int order_axis;  // the array whose order the node's references keep (-1: by primitive id)
  std::uint32_t depth;
};

struct Sweep {
  float cost = std::numeric_limits<float>::infinity();
  int axis = -1;
  std::size_t left_count = 0;
};

// The exact SAH sweep over each axis's sorted range; the first axis wins ties, as before.
Sweep sweep(const Context& ctx, const Task& t, const Box3f& box) {
  const std::size_t n = t.end - t.begin;
  const float area = box.half_area();
  Sweep best;
  if (area <= 0.0f || n < 2) return best;
  thread_local std::vector<Box3f> right;
  right.resize(n);
  const auto& o = ctx.o;
  for (int a = 0; a < 3; ++a) {
    const std::uint32_t* ids = ctx.sorted[a].data() + t.begin;
    Box3f acc;
    for (std::size_t i = n; i-- > 1;) acc.grow(ctx.refs[ids[i]].box), right[i] = acc;
    Box3f left;
    for (std::size_t i = 0; i + 1 < n; ++i) {
      left.grow(ctx.refs[ids[i]].box);
      const float cost = o.traversal_cost + o.intersection_cost *
                                                (left.half_area() * float(i + 1) +
                                                 right[i + 1].half_area() * float(n - i - 1)) /
                                                area;
      if (cost < best.cost) best = {cost, a, i + 1};
    }
  }
  return best;
}

// Stable partition of every axis's range by goes_left, through a scratch buffer.
void partition_all(const Context& ctx, const Task& t, std::size_t left_count) {
  thread_local std::vector<std::uint32_t> scratch;
  scratch.resize(t.end - t.begin);
  for (int a = 0; a < 3; ++a) {
    std::uint32_t* ids = ctx.sorted[a].data() + t.begin;
    std::size_t l = 0, r = left_count;
    for (std::size_t i = 0; i < t.end - t.begin; ++i)
      scratch[ctx.goes_left[ids[i]] ? l++ : r++] = ids[i];
    std::copy(scratch.begin(), scratch.end(), ids);
  }
}

std::span<const std::uint32_t> ids_in_order(const Context& ctx, const Task& t,
                                            std::vector<std::uint32_t>& by_id) {
  if (t.order_axis >= 0) return {ctx.sorted[t.order_axis].data() + t.begin, t.end - t.begin};
  by_id.assign(ctx.sorted[0].begin() + std::ptrdiff_t(t.begin),
               ctx.sorted[0].begin() + std::ptrdiff_t(t.end));
  std::sort(by_id.begin(), by_id.end());  // only the root has no axis order
  return by_id;
}

std::uint32_t append_leaf(const Context& ctx, const Task& t, const Box3f& box,
                          std::vector<format::BvhNode>& nodes) {
  std::vector<std::uint32_t> by_id;
  const auto ids = ids_in_order(ctx, t, by_id);
  std::copy(ids.begin(), ids.end(), ctx.order.begin() + std::ptrdiff_t(t.begin));
  format::BvhNode node{};
  for (int a = 0; a < 3; ++a)
    node.min[a] = format::at(box.min, a), node.max[a] = format::at(box.max, a);
  node.offset = std::uint32_t(t.begin);
  node.count = std::uint16_t(t.end - t.begin);
  nodes.push_back(node);
  return std::uint32_t(nodes.size() - 1);
}

void emit(const Context& ctx, const Task& t, std::vector<format::BvhNode>& nodes);

void emit(const Context& ctx, const Task& t, std::vector<format::BvhNode>& nodes) {
  const std::size_t n = t.end - t.begin;
  Box3f box;
  for (std::size_t i = t.begin; i < t.end; ++i) box.grow(ctx.refs[ctx.sorted[0][i]].box);
  const auto& o = ctx.o;
  const bool must_stop = t.depth + 1 >= format::kBvhMaxDepth;
  if (n <= 1 || must_stop) {
    if (n > format::kBvhMaxLeafSize)
      throw std::runtime_error("BVH: " + std::to_string(n) + " references left at maximum depth");
    append_leaf(ctx, t, box, nodes);
    return;
  }
  const Sweep s = sweep(ctx, t, box);
  if ((s.axis < 0 || s.cost >= o.intersection_cost * float(n)) && n <= o.max_leaf_size) {
    // A leaf keeps the order of its own best split's axis, as the sorting builder left it.
    append_leaf(ctx, {t.begin, t.end, s.axis >= 0 ? s.axis : t.order_axis, t.depth}, box, nodes);
    return;
  }
  // No split separates the centroids: halve the list in its current order.
  std::vector<std::uint32_t> by_id;
  const auto ids = s.axis >= 0
                       ? std::span<const std::uint32_t>(ctx.sorted[s.axis].data() + t.begin, n)
                       : ids_in_order(ctx, t, by_id);
  const std::size_t left_count = s.axis >= 0 ? s.left_count : n / 2;
  for (std::size_t i = 0; i < n; ++i) ctx.goes_left[ids[i]] = i < left_count;
  partition_all(ctx, t, left_count);
  const std::size_t index = append_leaf(ctx, t, box, nodes);  // made interior below
  nodes[index].axis = std::uint8_t(std::max(s.axis, 0));
  const int axis = s.axis >= 0 ? s.axis : t.order_axis;
  const Task left{t.begin, t.begin + left_count, axis, t.depth + 1};
  const Task right{t.begin + left_count, t.end, axis, t.depth + 1};
  const bool fork = t.depth < ctx.parallel_depth && left_count >= kParallelSubtree &&
                    n - left_count >= kParallelSubtree;
  emit_bvh_children(fork, left, right, index, nodes,
                    [&](const Task& child, auto& out) { emit(ctx, child, out); });
}

}  // namespace

std::vector<format::BvhNode> build_sweep_nodes(std::span<const PrimRef> refs,
                                               std::vector<std::uint32_t>& order,
                                               const BvhBuildOptions& options) {
  std::vector<std::uint32_t> sorted[3];
  parallel_for(3, options.threads, [&](std::size_t a) {
    sorted[a].resize(refs.size());
    std::iota(sorted[a].begin(), sorted[a].end(), 0u);
    std::sort(sorted[a].begin(), sorted[a].end(), [&](std::uint32_t x, std::uint32_t y) {
      const float cx = refs[x].box.centroid(int(a)), cy = refs[y].box.centroid(int(a));
      return cx < cy || (cx == cy && x < y);
    });
  });
  std::vector<std::uint8_t> goes_left(refs.size());
  order.assign(refs.size(), 0);
  const Context ctx{refs, sorted, goes_left, order, options, fork_depth(options.threads)};
  std::vector<format::BvhNode> nodes;
  emit(ctx, {0, refs.size(), -1, 0}, nodes);
  return nodes;
}

}  // namespace kiln
