// The polygon index's top-level table (PolygonIndexTopGrid): derived at open from the nodes the
// view has validated, so it holds no bytes of its own to check, and used by every point query to
// skip the first k levels of the descent with one lookup.
#include <algorithm>
#include <cmath>

#include "kiln/runtime/polygon_index.hpp"

namespace kiln {

using format::Box2d;
using format::Double2;

namespace {

// The split lines of level `level` along one axis, each level's midpoints computed exactly as
// quadtree_child_box computes them: 0.5 * lo + 0.5 * hi.
std::vector<double> split_lines(double lo, double hi, std::uint32_t level) {
  std::vector<double> s{lo, hi};
  for (std::uint32_t l = 0; l < level; ++l) {
    std::vector<double> next(2 * s.size() - 1);
    for (std::size_t i = 0; i + 1 < s.size(); ++i) {
      next[2 * i] = s[i];
      next[2 * i + 1] = 0.5 * s[i] + 0.5 * s[i + 1];
    }
    next.back() = s.back();
    s = std::move(next);
  }
  return s;
}

// Names `node` (at depth `depth`, covering cells [x0, x0 + size) x [y0, y0 + size) of level k)
// in its cells, or recurses into its children above level k.
void fill(const PolygonIndexParts& parts, PolygonIndexTopGrid& g, std::uint32_t node,
          std::uint32_t depth, std::uint32_t x0, std::uint32_t y0) {
  const std::uint32_t size = 1u << (g.level - depth), side = 1u << g.level;
  const format::PolygonIndexNode& n = parts.nodes[node];
  if (n.is_leaf() || depth == g.level) {
    for (std::uint32_t y = y0; y < y0 + size; ++y)
      for (std::uint32_t x = x0; x < x0 + size; ++x) {
        g.node[std::size_t(y) * side + x] = node;
        g.node_level[std::size_t(y) * side + x] = std::uint8_t(depth);
      }
    return;
  }
  const std::uint32_t half = size / 2;
  for (std::uint32_t c = 0; c < 4; ++c)
    fill(parts, g, n.first + c, depth + 1, x0 + (c & 1u ? half : 0), y0 + (c & 2u ? half : 0));
}

// The largest j < 2^k with lines[j] <= v, for v inside [lines.front(), lines.back()]: the
// column the descent reaches (it sends v >= a split line to the upper side). `guess` is the
// uniform estimate; the split lines are non-decreasing, so the walks end.
std::uint32_t column(std::span<const double> lines, double v, double guess) {
  const auto last = std::uint32_t(lines.size() - 2);
  std::uint32_t j = guess > 0 ? std::min(last, std::uint32_t(std::min(guess, 4294967295.0))) : 0;
  while (j > 0 && lines[j] > v) --j;
  while (j < last && lines[j + 1] <= v) ++j;
  return j;
}

}  // namespace

std::shared_ptr<const PolygonIndexTopGrid> make_polygon_index_top_grid(
    const PolygonIndexParts& parts) {
  auto g = std::make_shared<PolygonIndexTopGrid>();
  // 4^k cells for at most about 4 cells per node, and k <= 8 (256 KB of node indices): deeper
  // tables cost more cache misses than the levels they skip.
  while (g->level < 8 && (std::uint64_t(4) << (2 * g->level)) <= 4 * parts.nodes.size()) ++g->level;
  g->xs = split_lines(parts.bounds.min.x, parts.bounds.max.x, g->level);
  g->ys = split_lines(parts.bounds.min.y, parts.bounds.max.y, g->level);
  const std::size_t cells = std::size_t(1) << (2 * g->level);
  g->node.resize(cells);
  g->node_level.resize(cells);
  fill(parts, *g, 0, 0, 0, 0);
  const auto offsets = parts.layer.feature_polygons;
  // Bounded by the table's size too: a view made from raw parts has no Blob::open checks.
  g->feature.assign(parts.layer.polygon_count(), PolygonQueries::kNone);
  for (std::size_t f = 0; f + 1 < offsets.size(); ++f)
    for (std::uint64_t q = offsets[f];
         q < std::min<std::uint64_t>(offsets[f + 1], g->feature.size()); ++q)
      g->feature[q] = std::uint32_t(f);
  return g;
}

// The node named by the table for p (inside the bounds), and its cell in `box`.
const format::PolygonIndexNode* PolygonIndexView::top_cell(const Double2& p, Box2d& box) const {
  const PolygonIndexTopGrid& g = *top_;
  const double side = double(1u << g.level);
  const Box2d& b = parts_.bounds;
  const std::uint32_t ix = column(g.xs, p.x, (p.x - b.min.x) / (b.max.x - b.min.x) * side);
  const std::uint32_t iy = column(g.ys, p.y, (p.y - b.min.y) / (b.max.y - b.min.y) * side);
  const std::size_t cell = std::size_t(iy) << g.level | ix;
  const std::uint32_t shift = g.level - g.node_level[cell];
  const std::uint32_t x0 = ix >> shift << shift, y0 = iy >> shift << shift;
  box = {{g.xs[x0], g.ys[y0]}, {g.xs[x0 + (1u << shift)], g.ys[y0 + (1u << shift)]}};
  return &parts_.nodes[g.node[cell]];
}

}  // namespace kiln
