// The polygon index view: the validating walk at open, and the queries (descend to the leaf
// holding the point, then decide each listed polygon by its wholly-inside mark or by the parity
// of its listed edges' crossings with the ray from the point towards +x).
#include <algorithm>
#include <cstring>
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
  if (!top_)
    throw BlobError("polygon index '" + name +
                    "': leaves share entries or entries share edges (its leaf records would "
                    "outgrow its sections)");
}

namespace {

[[noreturn]] void fail(const std::string& name, const std::string& what) {
  throw BlobError("polygon index '" + name + "': " + what);
}

// Every leaf, reached or not (the leaf records built at open read them all): entries in range,
// and leaves own disjoint ranges, so the walks over leaves read each entry at most once.
void check_leaf_ranges(const PolygonIndexParts& p, const std::string& name) {
  std::uint64_t leaf_entries = 0;
  for (std::size_t i = 0; i < p.nodes.size(); ++i) {
    const PolygonIndexNode& n = p.nodes[i];
    if (!n.is_leaf()) continue;
    if (std::uint64_t(n.first) + n.count > p.entries.size())
      fail(name, "leaf " + std::to_string(i) + " has entries out of range");
    if ((leaf_entries += n.count) > p.entries.size()) fail(name, "leaves share entries");
  }
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
  if (p.nodes.size() > 0x7FFFFFFFu) fail(name, "has 2^31 nodes or more");
  std::vector<bool> reached(p.nodes.size());
  std::vector<std::pair<std::uint32_t, std::uint32_t>> stack{{0, 0}};  // node, depth
  reached[0] = true;
  check_leaf_ranges(p, name);
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

// Edges in blocks of 64: first the box test of every edge of the block without a branch (a bit
// per edge meeting the segment's box; most edges of a cell miss it), then the exact test only
// for the few set bits, so the loop's branches do not depend on the data edge by edge.
bool PolygonIndexView::entry_contains(const PolygonIndexEntry& e, const Box2d& cell,
                                      const Double2& p, Cost* cost) const {
  if (e.wholly_inside()) return true;
  const auto vertices = parts_.layer.vertices;
  const Double2 c = format::quadtree_centre(cell);
  const Double2 lo{std::min(c.x, p.x), std::min(c.y, p.y)};
  const Double2 hi{std::max(c.x, p.x), std::max(c.y, p.y)};
  bool inside = e.centre_inside();
  const auto edges = parts_.edges.subspan(e.first_edge, e.edges());
  for (std::size_t i = 0; i < edges.size(); i += 64) {
    const std::size_t n = std::min<std::size_t>(64, edges.size() - i);
    std::uint64_t hits = 0;
    for (std::size_t j = 0; j < n; ++j) {
      const Double2& a = vertices[edges[i + j].a];
      const Double2& b = vertices[edges[i + j].b];
      const bool miss = (std::max(a.x, b.x) < lo.x) | (std::min(a.x, b.x) > hi.x) |
                        (std::max(a.y, b.y) < lo.y) | (std::min(a.y, b.y) > hi.y);
      hits |= std::uint64_t(!miss) << j;
    }
    for (; hits; hits &= hits - 1) {
      const PolygonIndexEdge& edge = edges[i + std::size_t(__builtin_ctzll(hits))];
      inside ^= detail::shifted_segment_crosses_unboxed(c, p, vertices[edge.a], vertices[edge.b]);
    }
  }
  if (cost) cost->tests += e.edges();
  return inside;
}

namespace {

// The largest j < 2^k with lines[j] <= v, for v inside [lines.front(), lines.back()]: the
// column the descent reaches (it sends v >= a split line to the upper side). `guess` is the
// uniform estimate; the split lines are non-decreasing, so the walks end.
inline std::uint32_t column(const std::vector<double>& lines, double v, double guess) {
  const auto last = std::uint32_t(lines.size() - 2);
  std::uint32_t j = guess > 0 ? std::min(last, std::uint32_t(std::min(guess, 4294967295.0))) : 0;
  while (j > 0 && lines[j] > v) --j;
  while (j < last && lines[j + 1] <= v) ++j;
  return j;
}

}  // namespace

// The table cell holding p (inside the bounds), its column and row.
inline std::size_t PolygonIndexView::top_cell(const Double2& p, std::uint32_t& ix,
                                              std::uint32_t& iy) const {
  const PolygonIndexTopGrid& g = *top_;
  const Box2d& b = parts_.bounds;
  ix = column(g.xs, p.x, (p.x - b.min.x) * g.scale.x);
  iy = column(g.ys, p.y, (p.y - b.min.y) * g.scale.y);
  return std::size_t(iy) << g.level | ix;
}

// The box of the node the table names for cell (ix, iy): apart from top_cell, since most
// queries end at the cell's code without it.
inline Box2d PolygonIndexView::top_box(std::size_t cell, std::uint32_t ix, std::uint32_t iy) const {
  const PolygonIndexTopGrid& g = *top_;
  const std::uint32_t shift = g.level - g.node_level[cell];
  const std::uint32_t x0 = ix >> shift << shift, y0 = iy >> shift << shift;
  return {{g.xs[x0], g.ys[y0]}, {g.xs[x0 + (1u << shift)], g.ys[y0 + (1u << shift)]}};
}

// Calls visit(entry, cell) for each entry of the leaf holding p, in order, until it returns
// false.
template <class Visit>
void PolygonIndexView::visit_leaf(const Double2& p, Visit&& visit, Cost* cost) const {
  if (!parts_.bounds.contains(p)) return;
  std::uint32_t ix, iy;
  const std::size_t cell = top_cell(p, ix, iy);  // one lookup for the first levels
  Box2d box = top_box(cell, ix, iy);
  const PolygonIndexNode* n = &parts_.nodes[top_->node[cell]];
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

// A leaf record's answer for p: its entries in order, each wholly inside or decided by its
// inline edges as entry_contains decides it (the same doubles, so the same answers).
std::uint32_t PolygonIndexView::record_locate(const PolygonIndexTopGrid::Unit* unit,
                                              std::uint32_t entries, const Box2d& cell,
                                              const Double2& p) const {
  const Double2 c = format::quadtree_centre(cell);
  const Double2 lo{std::min(c.x, p.x), std::min(c.y, p.y)};
  const Double2 hi{std::max(c.x, p.x), std::max(c.y, p.y)};
  for (std::uint32_t k = 0; k < entries; ++k) {
    PolygonIndexTopGrid::Head head;
    std::memcpy(&head, unit++, sizeof head);
    if (head.edges == format::kPolygonWhollyInside) return head.feature;
    const std::uint32_t count = head.edges & ~format::kPolygonCentreInside;
    bool inside = (head.edges & format::kPolygonCentreInside) != 0;
    for (std::uint32_t i = 0; i < count; i += 64) {
      const std::uint32_t n = std::min<std::uint32_t>(64, count - i);
      std::uint64_t hits = 0;
      for (std::uint32_t j = 0; j < n; ++j) {
        const double* e = unit[i + j].v;  // a.x, a.y, b.x, b.y
        const bool miss = (std::max(e[0], e[2]) < lo.x) | (std::min(e[0], e[2]) > hi.x) |
                          (std::max(e[1], e[3]) < lo.y) | (std::min(e[1], e[3]) > hi.y);
        hits |= std::uint64_t(!miss) << j;
      }
      for (; hits; hits &= hits - 1) {
        const double* e = unit[i + std::uint32_t(__builtin_ctzll(hits))].v;
        inside ^= detail::shifted_segment_crosses_unboxed(c, p, {e[0], e[1]}, {e[2], e[3]});
      }
    }
    if (inside) return head.feature;
    unit += count;
  }
  return PolygonQueries::kNone;
}

// The hot path: a cell answering alike for all its points ends at the table; else the descent
// below it and the leaf's entries in order, as visit_leaf does.
[[gnu::always_inline]] inline std::uint32_t PolygonIndexView::locate_inline(
    const Double2& p) const {
  if (!parts_.bounds.contains(p)) return PolygonQueries::kNone;
  std::uint32_t ix, iy;
  const std::size_t cell = top_cell(p, ix, iy);
  // A bit per cell (8 KB at k = 8, cached) settles empty space without loading the code.
  if (top_->empty[cell / 64] >> (cell % 64) & 1) return PolygonQueries::kNone;
  const std::uint32_t code = top_->code[cell];
  if (code & PolygonIndexTopGrid::kAnswer) {
    const std::uint32_t f = code & PolygonIndexTopGrid::kNoFeature;
    return f == PolygonIndexTopGrid::kNoFeature ? PolygonQueries::kNone : f;
  }
  Box2d box = top_box(cell, ix, iy);
  const auto& nodes = top_->nodes;
  const PolygonIndexNode* n = &nodes[code];
  while (!n->is_leaf()) {
    const std::uint32_t child = format::quadtree_child_of(box, p);
    box = format::quadtree_child_box(box, child);
    n = &nodes[n->first + child];
  }
  return record_locate(&top_->units[n->first], n->count, box, p);
}

std::uint32_t PolygonIndexView::locate(const Double2& p) const {
  return locate_inline(p);
}

// Groups of 32 points go through each stage together (table lookups, then the descent one
// level at a time, then the records), each stage prefetching what the next one reads: the
// group's cache misses overlap instead of forming one dependent chain per point. Answers are
// locate's: the same steps on the same doubles.
void PolygonIndexView::locate_many(std::span<const Double2> points,
                                   std::span<std::uint32_t> out) const {
  constexpr std::size_t kGroup = 32;
  const std::size_t n = std::min(points.size(), out.size());
  const PolygonIndexTopGrid& g = *top_;
  std::uint32_t ix[kGroup], iy[kGroup], node[kGroup], active[kGroup];
  std::size_t cell[kGroup];
  Box2d box[kGroup];
  for (std::size_t base = 0; base < n; base += kGroup) {
    const std::size_t m = std::min(kGroup, n - base);
    std::size_t live = 0;
    for (std::size_t k = 0; k < m; ++k) {
      out[base + k] = PolygonQueries::kNone;
      if (!parts_.bounds.contains(points[base + k])) continue;
      cell[k] = top_cell(points[base + k], ix[k], iy[k]);
      __builtin_prefetch(&g.code[cell[k]]);
      active[live++] = std::uint32_t(k);
    }
    std::size_t next = 0;
    for (std::size_t a = 0; a < live; ++a) {
      const std::uint32_t k = active[a];
      if (g.empty[cell[k] / 64] >> (cell[k] % 64) & 1) continue;
      const std::uint32_t code = g.code[cell[k]];
      if (code & PolygonIndexTopGrid::kAnswer) {
        const std::uint32_t f = code & PolygonIndexTopGrid::kNoFeature;
        out[base + k] = f == PolygonIndexTopGrid::kNoFeature ? PolygonQueries::kNone : f;
        continue;
      }
      box[k] = top_box(cell[k], ix[k], iy[k]);
      node[k] = code;
      __builtin_prefetch(&g.nodes[code]);
      active[next++] = k;
    }
    live = next;
    // Descend one level per pass; a point reaching its leaf prefetches its record's head.
    std::size_t descending = live;
    while (descending > 0) {
      descending = 0;
      for (std::size_t a = 0; a < live; ++a) {
        const std::uint32_t k = active[a];
        const PolygonIndexNode& nd = g.nodes[node[k]];
        if (nd.is_leaf()) continue;
        const std::uint32_t child = format::quadtree_child_of(box[k], points[base + k]);
        box[k] = format::quadtree_child_box(box[k], child);
        node[k] = nd.first + child;
        const PolygonIndexNode& next_node = g.nodes[node[k]];
        __builtin_prefetch(&next_node);
        ++descending;
      }
    }
    for (std::size_t a = 0; a < live; ++a) {
      const std::uint32_t k = active[a];
      const PolygonIndexNode& nd = g.nodes[node[k]];
      if (nd.count) __builtin_prefetch(&g.units[nd.first]);
    }
    for (std::size_t a = 0; a < live; ++a) {
      const std::uint32_t k = active[a];
      const PolygonIndexNode& nd = g.nodes[node[k]];
      out[base + k] = record_locate(&g.units[nd.first], nd.count, box[k], points[base + k]);
    }
  }
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
