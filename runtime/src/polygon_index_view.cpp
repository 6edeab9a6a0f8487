// The polygon index view: the validating walk at open, and the queries (descend to the leaf
// holding the point, then decide each listed polygon by its wholly-inside mark or by the parity
// of its listed edges' crossings with the ray from the point towards +x).
#include <algorithm>
#include <string>
#include <vector>

#include "kiln/runtime/error.hpp"
#include "kiln/runtime/polygon_index.hpp"
#include "kiln/runtime/predicates2.hpp"
#include "predicates2_inline.hpp"

namespace kiln {

using format::Box2d;
using format::Double2;
using format::PolygonIndexEdge;
using format::PolygonIndexEntry;
using format::PolygonIndexNode;

PolygonIndexView::PolygonIndexView(const PolygonIndexParts& parts, const std::string& name)
    : parts_(parts) {
  validate(name);
  top_ = make_polygon_index_top_grid(parts_);
}

namespace {

[[noreturn]] void fail(const std::string& name, const std::string& what) {
  throw BlobError("polygon index '" + name + "': " + what);
}

}  // namespace

// Each node reached once from the root, children stored after their parent, depth bounded;
// every leaf's entries, their polygons and edge ranges, and every edge's vertices in range.
void PolygonIndexView::validate(const std::string& name) const {
  const auto& p = parts_;
  if (p.nodes.empty()) fail(name, "has no nodes");
  if (p.layer.feature_polygons.empty() || p.layer.polygon_rings.empty())
    fail(name, "has no polygon layer");
  if (p.layer.polygon_count() > 0xFFFFFFFEu || p.layer.vertices.size() > 0xFFFFFFFFu)
    fail(name, "indexes a layer too large for 32-bit indices");
  std::vector<bool> reached(p.nodes.size());
  std::vector<std::pair<std::uint32_t, std::uint32_t>> stack{{0, 0}};  // node, depth
  reached[0] = true;
  while (!stack.empty()) {
    const auto [index, depth] = stack.back();
    stack.pop_back();
    const PolygonIndexNode& n = p.nodes[index];
    if (!n.is_leaf()) {
      if (n.first <= index || p.nodes.size() < 4 || n.first > p.nodes.size() - 4)
        fail(name, "node " + std::to_string(index) + " has children out of order or range");
      if (depth + 1 > format::kPolygonIndexMaxDepth)
        fail(name, "is deeper than " + std::to_string(format::kPolygonIndexMaxDepth));
      for (std::uint32_t c = n.first; c < n.first + 4; ++c) {
        if (reached[c]) fail(name, "node " + std::to_string(c) + " is reached twice");
        reached[c] = true;
        stack.emplace_back(c, depth + 1);
      }
      continue;
    }
    if (std::uint64_t(n.first) + n.count > p.entries.size())
      fail(name, "leaf " + std::to_string(index) + " has entries out of range");
    for (std::uint32_t i = n.first + 1; i < n.first + n.count; ++i)
      if (p.entries[i].polygon <= p.entries[i - 1].polygon)
        fail(name, "entry " + std::to_string(i) + " names a polygon out of order");
  }
  // Every entry, reached or not (kiln verify reads them all).
  for (std::size_t i = 0; i < p.entries.size(); ++i) {
    const PolygonIndexEntry& e = p.entries[i];
    if (e.polygon >= p.layer.polygon_count())
      fail(name, "entry " + std::to_string(i) + " names a polygon out of range");
    if (std::uint64_t(e.first_edge) + e.edges() > p.edges.size())
      fail(name, "entry " + std::to_string(i) + " has edges out of range");
  }
  const std::uint64_t vertices = p.layer.vertices.size();
  for (std::size_t i = 0; i < p.edges.size(); ++i)
    if (p.edges[i].a >= vertices || p.edges[i].b >= vertices)
      fail(name, "edge " + std::to_string(i) + " names a vertex out of range");
}

std::uint32_t PolygonIndexView::feature_of(std::uint32_t polygon) const {
  // Tabled at open: the feature f with feature_polygons[f] <= polygon < feature_polygons[f + 1].
  return polygon < top_->feature.size() ? top_->feature[polygon] : PolygonQueries::kNone;
}

bool PolygonIndexView::entry_contains(const PolygonIndexEntry& e, const Box2d& cell,
                                      const Double2& p, Cost* cost) const {
  if (e.wholly_inside()) return true;
  const auto vertices = parts_.layer.vertices;
  const Double2 centre = format::quadtree_centre(cell);
  bool inside = e.centre_inside();
  for (const PolygonIndexEdge& edge : parts_.edges.subspan(e.first_edge, e.edges()))
    inside ^= detail::shifted_segment_crosses_inline(centre, p, vertices[edge.a], vertices[edge.b]);
  if (cost) cost->tests += e.edges();
  return inside;
}

// Calls visit(entry, cell) for each entry of the leaf holding p, in order, until it returns
// false.
template <class Visit>
void PolygonIndexView::visit_leaf(const Double2& p, Visit&& visit, Cost* cost) const {
  if (!parts_.bounds.contains(p)) return;
  Box2d box;
  const PolygonIndexNode* n = top_cell(p, box);  // one lookup for the first levels
  if (cost) ++cost->nodes;
  while (!n->is_leaf()) {
    const std::uint32_t child = format::quadtree_child_of(box, p);
    box = format::quadtree_child_box(box, child);
    n = &parts_.nodes[n->first + child];
    if (cost) ++cost->nodes;
  }
  for (const PolygonIndexEntry& e : parts_.entries.subspan(n->first, n->count))
    if (!visit(e, box)) return;
}

std::uint32_t PolygonIndexView::locate(const Double2& p) const {
  std::uint32_t found = PolygonQueries::kNone;
  visit_leaf(
      p,
      [&](const PolygonIndexEntry& e, const Box2d& cell) {
        if (!entry_contains(e, cell, p, nullptr)) return true;
        found = feature_of(e.polygon);
        return false;
      },
      nullptr);
  return found;
}

std::uint32_t PolygonIndexView::locate_counting(const Double2& p, Cost& cost) const {
  std::uint32_t found = PolygonQueries::kNone;
  visit_leaf(
      p,
      [&](const PolygonIndexEntry& e, const Box2d& cell) {
        if (!entry_contains(e, cell, p, &cost)) return true;
        found = feature_of(e.polygon);
        return false;
      },
      &cost);
  return found;
}

void PolygonIndexView::locate_all(const Double2& p, std::vector<std::uint32_t>& out) const {
  out.clear();
  visit_leaf(
      p,
      [&](const PolygonIndexEntry& e, const Box2d& cell) {
        if (entry_contains(e, cell, p, nullptr)) {
          const std::uint32_t f = feature_of(e.polygon);
          if (out.empty() || out.back() != f) out.push_back(f);  // entries ascend by polygon
        }
        return true;
      },
      nullptr);
}

}  // namespace kiln
