// The polygon index's top-level table (PolygonIndexTopGrid): derived at open from the nodes the
// view has validated, so it holds no bytes of its own to check, and used by every point query to
// skip the first k levels of the descent with one lookup.
#include <algorithm>
#include <cmath>
#include <cstring>

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

// Each cell's code: the answer where the leaf covering it answers alike for all its points (no
// entry: none; a first entry wholly inside: that polygon's feature, the lowest containing any
// point, as entries ascend by polygon), else the node. The view refuses 2^31 nodes or more.
void classify(const PolygonIndexParts& parts, PolygonIndexTopGrid& g) {
  g.code.resize(g.node.size());
  g.empty.assign((g.node.size() + 63) / 64, 0);
  for (std::size_t cell = 0; cell < g.node.size(); ++cell) {
    const format::PolygonIndexNode& n = parts.nodes[g.node[cell]];
    std::uint32_t code = g.node[cell];
    if (n.is_leaf() && n.count == 0) {
      code = PolygonIndexTopGrid::kAnswer | PolygonIndexTopGrid::kNoFeature;
      g.empty[cell / 64] |= std::uint64_t(1) << (cell % 64);
    } else if (n.is_leaf() && parts.entries[n.first].wholly_inside()) {
      const std::uint32_t polygon = parts.entries[n.first].polygon;
      const std::uint32_t f = polygon < g.feature.size() ? g.feature[polygon] : ~0u;
      if (f < PolygonIndexTopGrid::kNoFeature) code = PolygonIndexTopGrid::kAnswer | f;
    }
    g.code[cell] = code;
  }
}

// The leaf records: each leaf's entries with their edges' endpoints inline, leaves in node order.
// False when they would hold more units than the entry and edge sections have elements: the
// builder never shares an entry between leaves nor an edge between entries, while forged ranges
// that overlap could make a small blob ask for a huge copy (the view then refuses it).
bool make_records(const PolygonIndexParts& parts, PolygonIndexTopGrid& g) {
  const std::uint64_t most =
      std::min<std::uint64_t>(parts.entries.size() + parts.edges.size(), 0xFFFFFFFFu);
  std::uint64_t units = 0;
  for (const format::PolygonIndexNode& n : parts.nodes) {
    if (n.is_leaf())
      for (const format::PolygonIndexEntry& e : parts.entries.subspan(n.first, n.count))
        units += 1 + e.edges();
    if (units > most) return false;  // per leaf: the count stays O(nodes + most)
  }
  g.units.reserve(units);
  g.nodes.assign(parts.nodes.begin(), parts.nodes.end());
  const auto v = parts.layer.vertices;
  for (format::PolygonIndexNode& n : g.nodes) {
    if (!n.is_leaf()) continue;
    const auto entries = parts.entries.subspan(n.first, n.count);
    n.first = std::uint32_t(g.units.size());
    for (const format::PolygonIndexEntry& e : entries) {
      const PolygonIndexTopGrid::Head head{
          e.polygon < g.feature.size() ? g.feature[e.polygon] : PolygonQueries::kNone,
          e.edge_count};
      PolygonIndexTopGrid::Unit unit{};
      std::memcpy(&unit, &head, sizeof head);
      g.units.push_back(unit);
      for (const format::PolygonIndexEdge& edge : parts.edges.subspan(e.first_edge, e.edges()))
        g.units.push_back({{v[edge.a].x, v[edge.a].y, v[edge.b].x, v[edge.b].y}});
    }
  }
  return true;
}

}  // namespace

std::shared_ptr<const PolygonIndexTopGrid> make_polygon_index_top_grid(
    const PolygonIndexParts& parts) {
  auto g = std::make_shared<PolygonIndexTopGrid>();
  // 4^k cells for at most about 16 cells per node, and k <= 9 (1 MB of codes): deeper tables
  // cost more cache misses than the levels they skip (docs/BENCHMARKS.md).
  while (g->level < 9 && (std::uint64_t(4) << (2 * g->level)) <= 16 * parts.nodes.size())
    ++g->level;
  g->xs = split_lines(parts.bounds.min.x, parts.bounds.max.x, g->level);
  g->ys = split_lines(parts.bounds.min.y, parts.bounds.max.y, g->level);
  const std::size_t cells = std::size_t(1) << (2 * g->level);
  g->node.resize(cells);
  g->node_level.resize(cells);
  const Box2d& b = parts.bounds;
  g->scale = {double(1u << g->level) / (b.max.x - b.min.x),
              double(1u << g->level) / (b.max.y - b.min.y)};
  fill(parts, *g, 0, 0, 0, 0);
  const auto offsets = parts.layer.feature_polygons;
  // Bounded by the table's size too: a view made from raw parts has no Blob::open checks.
  g->feature.assign(parts.layer.polygon_count(), PolygonQueries::kNone);
  for (std::size_t f = 0; f + 1 < offsets.size(); ++f)
    for (std::uint64_t q = offsets[f];
         q < std::min<std::uint64_t>(offsets[f + 1], g->feature.size()); ++q)
      g->feature[q] = std::uint32_t(f);
  classify(parts, *g);
  if (!make_records(parts, *g)) return nullptr;
  return g;
}

}  // namespace kiln
