// The polygon index's walks over many cells: the features meeting a box, the leaves for
// drawing, and the per-level statistics `kiln dump` prints.
#include <algorithm>
#include <utility>
#include <vector>

#include "kiln/runtime/polygon_index.hpp"
#include "kiln/runtime/predicates2.hpp"

namespace kiln {

using format::Box2d;
using format::Double2;
using format::PolygonIndexEntry;

namespace {

// Calls leaf(node index, box, depth) for each leaf whose closed box overlaps `query` (every
// leaf when `query` is null), interior(depth) for each interior node visited. The view's
// validation bounds the depth and makes the nodes a tree, so the stack stays small.
template <class Leaf, class Interior>
void walk(const PolygonIndexParts& p, const Box2d* query, Leaf&& leaf, Interior&& interior) {
  struct Item {
    std::uint32_t node, depth;
    Box2d box;
  };
  std::vector<Item> stack{{0, 0, p.bounds}};
  while (!stack.empty()) {
    const Item item = stack.back();
    stack.pop_back();
    if (query && !item.box.overlaps(*query)) continue;
    const auto& n = p.nodes[item.node];
    if (n.is_leaf()) {
      leaf(item.node, item.box, item.depth);
      continue;
    }
    interior(item.depth);
    for (std::uint32_t c = 4; c-- > 0;)
      stack.push_back({n.first + c, item.depth + 1, format::quadtree_child_box(item.box, c)});
  }
}

}  // namespace

void PolygonIndexView::features_in_box(const Box2d& box, std::vector<std::uint32_t>& out) const {
  out.clear();
  const auto vertices = parts_.layer.vertices;
  auto meets = [&](const PolygonIndexEntry& e, const Box2d& cell) {
    if (e.wholly_inside()) return true;
    // The polygon's boundary meets the box: its closed area does.
    for (const auto& edge : parts_.edges.subspan(e.first_edge, e.edges()))
      if (segment_meets_box(vertices[edge.a], vertices[edge.b], box.min, box.max)) return true;
    // Else no boundary crosses box ∩ cell (the entry lists every edge meeting the cell), which
    // lies wholly inside or outside the polygon: one of its points decides.
    const Double2 corner{std::max(box.min.x, cell.min.x), std::max(box.min.y, cell.min.y)};
    return entry_contains(e, cell, corner, nullptr);
  };
  walk(
      parts_, &box,
      [&](std::uint32_t node, const Box2d& cell, std::uint32_t) {
        const auto& n = parts_.nodes[node];
        for (const PolygonIndexEntry& e : parts_.entries.subspan(n.first, n.count)) {
          const std::uint32_t f = feature_of(e.polygon);
          if ((out.empty() || out.back() != f) && meets(e, cell)) out.push_back(f);
        }
      },
      [](std::uint32_t) {});
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
}

void PolygonIndexView::cells(std::vector<IndexCell2>& out) const {
  out.clear();
  std::vector<std::pair<std::uint32_t, IndexCell2>> leaves;
  walk(
      parts_, nullptr,
      [&](std::uint32_t node, const Box2d& box, std::uint32_t depth) {
        const auto& n = parts_.nodes[node];
        std::uint64_t edges = 0;
        for (const PolygonIndexEntry& e : parts_.entries.subspan(n.first, n.count))
          edges += e.edges();
        leaves.push_back({node, {box, depth, std::uint32_t(std::min<std::uint64_t>(edges, ~0u))}});
      },
      [](std::uint32_t) {});
  std::sort(leaves.begin(), leaves.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  for (const auto& [node, cell] : leaves) out.push_back(cell);
}

std::vector<PolygonIndexLevel> PolygonIndexView::levels() const {
  std::vector<PolygonIndexLevel> levels;
  auto at = [&](std::uint32_t depth) -> PolygonIndexLevel& {
    if (levels.size() <= depth) levels.resize(depth + 1);
    return levels[depth];
  };
  walk(
      parts_, nullptr,
      [&](std::uint32_t node, const Box2d&, std::uint32_t depth) {
        PolygonIndexLevel& level = at(depth);
        ++level.leaves;
        const auto& n = parts_.nodes[node];
        bool boundary = false;
        for (const PolygonIndexEntry& e : parts_.entries.subspan(n.first, n.count)) {
          ++level.entries;
          if (e.wholly_inside()) continue;
          boundary = true;
          level.edge_refs += e.edges();
        }
        level.boundary_leaves += boundary;
      },
      [&](std::uint32_t depth) { ++at(depth).interior; });
  return levels;
}

}  // namespace kiln
