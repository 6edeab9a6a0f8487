// Bucket PR quadtree construction (Finkel and Bentley 1974; the "PR" bucket variant of Samet's
// "The Design and Analysis of Spatial Data Structures", 1990): the root square over every point
// is cut into four equal quadrants until a cell holds at most `bucket_size` points, reaches
// `max_depth`, or holds only copies of one point. Children are laid out depth first, so every
// subtree's nodes and points are contiguous.
#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

#include "kiln/compiler/quadtree_builder.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln {

namespace {

// Cells with at least this many points, near the root, build their quadrants in parallel; a
// subtree is a pure function of its points' order, which never depends on who builds it.
constexpr std::size_t kParallelPoints = 1 << 15;
constexpr std::uint32_t kParallelDepth = 2;

struct Context {
  std::span<const format::Double2> points;
  const QuadtreeBuildOptions& options;
};

bool all_coincide(const Context& ctx, std::span<const std::uint32_t> ids) {
  const format::Double2 first = ctx.points[ids[0]];
  return std::all_of(ids.begin(), ids.end(),
                     [&](std::uint32_t id) { return ctx.points[id] == first; });
}

// Reorders `ids` by quadrant of `cell`, keeping their order within a quadrant (a stable
// counting sort); returns where each quadrant's ids start, and the end.
std::array<std::size_t, 5> split_quadrants(const Context& ctx, std::span<std::uint32_t> ids,
                                           const format::Box2d& cell) {
  std::vector<std::uint8_t> quadrant(ids.size());
  std::array<std::size_t, 5> start{};
  for (std::size_t i = 0; i < ids.size(); ++i) {
    quadrant[i] = std::uint8_t(format::quad_quadrant(cell, ctx.points[ids[i]]));
    start[quadrant[i] + 1] += 1;
  }
  for (int q = 0; q < 4; ++q) start[q + 1] += start[q];
  std::vector<std::uint32_t> sorted(ids.size());
  std::array<std::size_t, 4> next{start[0], start[1], start[2], start[3]};
  for (std::size_t i = 0; i < ids.size(); ++i) sorted[next[quadrant[i]]++] = ids[i];
  std::copy(sorted.begin(), sorted.end(), ids.begin());
  return start;
}

// Appends `sub` (built as if it started at index 0) to `nodes`, shifting its end indices.
void append_shifted(std::vector<format::QuadNode>& nodes,
                    const std::vector<format::QuadNode>& sub) {
  const auto shift = std::uint32_t(nodes.size());
  for (const format::QuadNode& n : sub)
    nodes.push_back(
        format::QuadNode::make(n.first, n.count, n.end() + shift, n.is_leaf(), n.quadrant()));
}

// Appends the subtree over ids[begin, end) (quadrant `quadrant` of its parent, cell `cell`) to
// `nodes` in depth-first order; end indices count from nodes[0].
void build_subtree(const Context& ctx, std::span<std::uint32_t> ids, std::size_t begin,
                   std::size_t end, std::uint32_t quadrant, std::uint32_t depth,
                   const format::Box2d& cell, std::vector<format::QuadNode>& nodes) {
  const auto range = ids.subspan(begin, end - begin);
  const std::size_t self = nodes.size();
  if (range.size() <= ctx.options.bucket_size || depth >= ctx.options.max_depth ||
      all_coincide(ctx, range)) {
    // Ascending ids inside a bucket: the output does not depend on how cells ordered them.
    std::sort(range.begin(), range.end());
    nodes.push_back(format::QuadNode::make(std::uint32_t(begin), std::uint32_t(range.size()),
                                           std::uint32_t(self + 1), true, quadrant));
    return;
  }
  nodes.push_back({});
  const auto start = split_quadrants(ctx, range, cell);
  auto child = [&](std::uint32_t q, std::vector<format::QuadNode>& out) {
    build_subtree(ctx, ids, begin + start[q], begin + start[q + 1], q, depth + 1,
                  format::quad_child_cell(cell, q), out);
  };
  if (depth < kParallelDepth && range.size() >= kParallelPoints) {
    std::array<std::vector<format::QuadNode>, 4> parts;
    parallel_for(4, ctx.options.threads, [&](std::size_t q) {
      if (start[q] != start[q + 1]) child(std::uint32_t(q), parts[q]);
    });
    for (const auto& part : parts) append_shifted(nodes, part);
  } else {
    for (std::uint32_t q = 0; q < 4; ++q)
      if (start[q] != start[q + 1]) child(q, nodes);
  }
  if (nodes.size() > format::kQuadMaxNodes)
    throw std::length_error("quadtree needs more than 2^29 nodes; raise bucket-size");
  nodes[self] = format::QuadNode::make(std::uint32_t(begin), std::uint32_t(range.size()),
                                       std::uint32_t(nodes.size()), false, quadrant);
}

// The root cell: the square on the bounds' lower corner whose side is their longer extent
// (square cells keep neighbour searches tight); grown to the bounds should rounding fall short.
format::Box2d root_square(const format::Box2d& b) {
  const double side = std::max(b.max.x - b.min.x, b.max.y - b.min.y);
  format::Box2d root{b.min, {b.min.x + side, b.min.y + side}};
  root.max.x = std::max(root.max.x, b.max.x);
  root.max.y = std::max(root.max.y, b.max.y);
  return root;
}

void check_input(std::span<const format::Double2> points, const QuadtreeBuildOptions& options) {
  if (points.empty()) throw std::invalid_argument("a quadtree needs at least one point");
  if (points.size() > 0xFFFFFFFFu)
    throw std::length_error("a quadtree holds at most 2^32 - 1 points");
  if (options.bucket_size < 1 || options.bucket_size > kMaxQuadBucketSize)
    throw std::invalid_argument("quadtree bucket size " + std::to_string(options.bucket_size) +
                                " is outside 1.." + std::to_string(kMaxQuadBucketSize));
  if (options.max_depth > format::kQuadMaxDepth)
    throw std::invalid_argument("quadtree max depth " + std::to_string(options.max_depth) +
                                " is above " + std::to_string(format::kQuadMaxDepth));
  for (std::size_t i = 0; i < points.size(); ++i)
    if (!std::isfinite(points[i].x) || !std::isfinite(points[i].y))
      throw std::invalid_argument("quadtree: point " + std::to_string(i) + " is not finite");
}

QuadtreeStatistics statistics_of(const FlatQuadtree& tree) {
  QuadtreeStatistics s;
  s.node_count = tree.nodes.size();
  s.point_count = tree.points.size();
  std::vector<std::pair<std::uint32_t, std::uint32_t>> stack{{0, 0}};
  while (!stack.empty()) {
    const auto [node, depth] = stack.back();
    stack.pop_back();
    const format::QuadNode& n = tree.nodes[node];
    s.depth = std::max(s.depth, depth);
    if (n.is_leaf()) {
      s.leaf_count += 1;
      s.largest_bucket = std::max(s.largest_bucket, n.count);
      continue;
    }
    for (std::uint32_t c = node + 1; c < n.end(); c = tree.nodes[c].end())
      stack.push_back({c, depth + 1});
  }
  const double bytes =
      double(tree.nodes.size() * sizeof(format::QuadNode)) +
      double(tree.points.size() * (sizeof(format::Double2) + sizeof(std::uint32_t)));
  s.bytes_per_point = bytes / double(tree.points.size());
  return s;
}

}  // namespace

FlatQuadtree build_quadtree(std::span<const format::Double2> points,
                            const QuadtreeBuildOptions& options) {
  check_input(points, options);
  FlatQuadtree tree;
  for (const auto& p : points) tree.bounds.grow(p);
  tree.root = root_square(tree.bounds);
  tree.ids.resize(points.size());
  for (std::uint32_t i = 0; i < tree.ids.size(); ++i) tree.ids[i] = i;
  const Context ctx{points, options};
  build_subtree(ctx, tree.ids, 0, tree.ids.size(), 0, 0, tree.root, tree.nodes);
  tree.points.reserve(points.size());
  for (const auto id : tree.ids) tree.points.push_back(points[id]);
  tree.stats = statistics_of(tree);
  return tree;
}

}  // namespace kiln
