// Point k-d tree construction: top-down, widest axis of the points' extent, median or sliding
// midpoint cut, leaves of at most `max_leaf_size` points (or any number of identical points).
#include <algorithm>
#include <stdexcept>

#include "kiln/compiler/point_tree_builder.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln {

std::string to_string(PointSplitRule rule) {
  return rule == PointSplitRule::kMedian ? "median" : "sliding-midpoint";
}

namespace {

// Sliding midpoint can peel one point per level off exponentially spaced data; below this depth
// every cut is a median, which halves the range, so no leaf is deeper than 24 + 32 + 1 levels.
constexpr std::uint32_t kSlidingMidpointDepth = 24;
static_assert(kSlidingMidpointDepth + 33 <= format::kPointMaxDepth);

// Ranges at least this large, near the root, build their halves on two threads; a subtree is a
// pure function of its points, so the tree does not depend on who builds it.
constexpr std::size_t kParallelPoints = 1 << 16;

float coordinate(const format::Float3& p, int axis) {
  return axis == 0 ? p.x : axis == 1 ? p.y : p.z;
}

struct Context {
  std::span<const format::Float3> points;
  const PointTreeBuildOptions& options;
  std::uint32_t parallel_depth;  // spawn threads above this depth
};

struct Cut {
  int axis = -1;  // -1: make a leaf
  std::size_t middle = 0;
  float plane = 0;  // where the children's cells meet
  float below_max = 0, above_min = 0;
};

// Chooses the cut of ids[begin, end), whose points lie in `cell`, and partitions the range.
Cut cut_range(const Context& ctx, std::span<std::uint32_t> ids, std::size_t begin, std::size_t end,
              std::uint32_t depth, const format::Box3f& cell) {
  Cut cut;
  if (end - begin <= ctx.options.max_leaf_size) return cut;
  format::Box3f box;
  for (std::size_t i = begin; i < end; ++i) box.grow(ctx.points[ids[i]]);
  auto spread = [&](int a) { return format::at(box.max, a) - format::at(box.min, a); };
  int axis = 0;
  for (int a = 1; a < 3; ++a)
    if (spread(a) > spread(axis)) axis = a;
  if (!(spread(axis) > 0.0f)) return cut;  // identical points: nothing separates them
  const auto first = ids.begin() + std::ptrdiff_t(begin), last = ids.begin() + std::ptrdiff_t(end);
  auto at = [&](std::uint32_t id) { return coordinate(ctx.points[id], axis); };  // reads `axis` now
  auto middle = last;
  if (ctx.options.split == PointSplitRule::kSlidingMidpoint && depth < kSlidingMidpointDepth) {
    // Maneewongvatana and Mount: halve the cell's longest side (of near-equal sides, the one the
    // points spread along most), sliding the plane onto the points when they all lie on one
    // side. Cells stay fat, so few cells lie near any query.
    float longest = 0.0f;
    for (int a = 0; a < 3; ++a)
      longest = std::max(longest, format::at(cell.max, a) - format::at(cell.min, a));
    for (int a = 0, best = -1; a < 3; ++a)
      if (format::at(cell.max, a) - format::at(cell.min, a) >= (1.0f - 1e-5f) * longest &&
          (best < 0 || spread(a) > spread(best)) && spread(a) > 0.0f)
        best = axis = a;
    // Halves written separately so huge coordinates cannot overflow to infinity.
    const float half = 0.5f * format::at(cell.min, axis) + 0.5f * format::at(cell.max, axis);
    const float split = std::clamp(half, format::at(box.min, axis), format::at(box.max, axis));
    middle = std::partition(first, last, [&](std::uint32_t id) { return at(id) < split; });
    if (middle == first)  // slid onto the lowest points: they go below
      middle = std::partition(first, last, [&](std::uint32_t id) { return at(id) <= split; });
    cut.plane = split;
  }
  if (middle == first || middle == last) {
    // Median, ordered by (coordinate, id) so ties split the same way on every standard library.
    middle = first + std::ptrdiff_t((end - begin) / 2);
    std::nth_element(first, middle, last, [&](std::uint32_t a, std::uint32_t b) {
      return at(a) < at(b) || (at(a) == at(b) && a < b);
    });
    cut.plane = at(*middle);
  }
  cut.axis = axis;
  cut.middle = std::size_t(middle - ids.begin());
  cut.below_max =
      at(*std::max_element(first, middle, [&](auto a, auto b) { return at(a) < at(b); }));
  cut.above_min =
      at(*std::min_element(middle, last, [&](auto a, auto b) { return at(a) < at(b); }));
  return cut;
}

// Appends the subtree over ids[begin, end) to `nodes` in pre-order (indices relative to `base`,
// the position `nodes[0]` will have in the final array).
void build_subtree(const Context& ctx, std::span<std::uint32_t> ids, std::size_t begin,
                   std::size_t end, std::uint32_t depth, const format::Box3f& cell,
                   std::vector<format::PointNode>& nodes) {
  const Cut cut = cut_range(ctx, ids, begin, end, depth, cell);
  if (cut.axis < 0) {
    // Ascending ids inside a leaf: the output does not depend on how partitioning ordered them.
    std::sort(ids.begin() + std::ptrdiff_t(begin), ids.begin() + std::ptrdiff_t(end));
    nodes.push_back(format::PointNode::leaf(std::uint32_t(begin), std::uint32_t(end - begin)));
    return;
  }
  const std::size_t self = nodes.size();
  nodes.push_back({});
  format::Box3f below_cell = cell, above_cell = cell;
  format::at(below_cell.max, cut.axis) = cut.plane;
  format::at(above_cell.min, cut.axis) = cut.plane;
  if (depth < ctx.parallel_depth && end - begin >= kParallelPoints) {
    std::vector<format::PointNode> above;  // built apart, appended after the below side
    fork_join(
        true, [&] { build_subtree(ctx, ids, begin, cut.middle, depth + 1, below_cell, nodes); },
        [&] { build_subtree(ctx, ids, cut.middle, end, depth + 1, above_cell, above); });
    const std::size_t shift = nodes.size();
    for (auto n : above) {
      if (!n.is_leaf())
        n = format::PointNode::interior(int(n.axis()), n.below_max(), n.above_min(),
                                        std::uint32_t(n.above_child() + shift));
      nodes.push_back(n);
    }
    nodes[self] =
        format::PointNode::interior(cut.axis, cut.below_max, cut.above_min, std::uint32_t(shift));
  } else {
    build_subtree(ctx, ids, begin, cut.middle, depth + 1, below_cell, nodes);
    const std::size_t above = nodes.size();
    nodes[self] =
        format::PointNode::interior(cut.axis, cut.below_max, cut.above_min, std::uint32_t(above));
    build_subtree(ctx, ids, cut.middle, end, depth + 1, above_cell, nodes);
  }
}

PointTreeStatistics statistics_of(const FlatPointTree& tree) {
  PointTreeStatistics s;
  s.node_count = tree.nodes.size();
  s.point_count = tree.points.size();
  std::vector<std::pair<std::uint32_t, std::uint32_t>> stack{{0, 1}};
  while (!stack.empty()) {
    const auto [node, depth] = stack.back();
    stack.pop_back();
    s.max_depth = std::max(s.max_depth, depth);
    const auto& n = tree.nodes[node];
    if (n.is_leaf()) {
      s.leaf_count += 1;
      s.largest_leaf = std::max(s.largest_leaf, n.point_count());
      continue;
    }
    stack.push_back({n.above_child(), depth + 1});
    stack.push_back({node + 1, depth + 1});
  }
  const double bytes =
      double(tree.nodes.size() * sizeof(format::PointNode)) +
      double(tree.points.size() * (sizeof(format::Float3) + sizeof(std::uint32_t)));
  s.bytes_per_point = bytes / double(tree.points.size());
  return s;
}

}  // namespace

FlatPointTree build_point_tree(std::span<const format::Float3> points,
                               const PointTreeBuildOptions& options) {
  if (points.empty()) throw std::invalid_argument("a point k-d tree needs at least one point");
  if (options.max_leaf_size < 1 || options.max_leaf_size > kMaxPointLeafSize)
    throw std::invalid_argument("point leaf size " + std::to_string(options.max_leaf_size) +
                                " is outside 1.." + std::to_string(kMaxPointLeafSize));
  FlatPointTree tree;
  tree.ids.resize(points.size());
  for (std::uint32_t i = 0; i < tree.ids.size(); ++i) tree.ids[i] = i;
  for (const auto& p : points) tree.bounds.grow(p);
  const Context ctx{points, options, fork_depth(options.threads)};
  build_subtree(ctx, tree.ids, 0, tree.ids.size(), 1, tree.bounds, tree.nodes);
  // Every child index is below the node count, so this one check covers the 30-bit fields.
  if (tree.nodes.size() > format::kPointMaxIndex)
    throw std::length_error("point k-d tree needs more than 2^30 nodes; raise --points-leaf-size");
  tree.points.reserve(points.size());
  for (const auto id : tree.ids) tree.points.push_back(points[id]);
  tree.stats = statistics_of(tree);
  return tree;
}

}  // namespace kiln
