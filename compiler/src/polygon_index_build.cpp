// The polygon index builder: a temporary quadtree built top down, then flattened into sibling
// groups in depth-first order. Each cell keeps, per polygon that may hold one of its points,
// the polygon's edges meeting the closed cell and whether the cell's centre is inside; the
// root's centre is decided by the crossing number over the whole polygon, a child's from its
// parent's by the parent's edges that the segment between the two centres crosses (so no cell
// ever scans a whole polygon). A polygon with no edge in the cell is wholly in or out of it.
#include <algorithm>
#include <array>
#include <memory>
#include <stdexcept>

#include "kiln/compiler/polygon_index_builder.hpp"
#include "kiln/runtime/parallel.hpp"
#include "kiln/runtime/predicates2.hpp"

namespace kiln {

using format::Box2d;
using format::Double2;

PolygonLayerView view_of(const PolygonLayer& layer) {
  PolygonLayerView v;
  v.vertices = layer.vertices;
  v.ring_vertices = layer.ring_vertices;
  v.polygon_rings = layer.polygon_rings;
  v.feature_polygons = layer.feature_polygons;
  v.ids = {layer.ids.offsets, layer.ids.bytes};
  v.names = {layer.names.offsets, layer.names.bytes};
  v.name_property = layer.name_property;
  v.features_skipped = layer.features_skipped;
  v.bounds = layer.bounds;
  return v;
}

namespace {

// A polygon in a cell: wholly inside, or its edges meeting the cell (first-vertex indices)
// and whether the cell's centre is inside.
struct Candidate {
  std::uint32_t polygon = 0;
  bool inside = false;  // wholly
  bool centre = false;
  std::vector<std::uint32_t> edges;
};

struct TempNode {
  std::vector<Candidate> entries;  // a leaf's
  std::array<std::unique_ptr<TempNode>, 4> children;
  bool leaf() const { return !children[0]; }
};

struct Context {
  const PolygonLayerView& layer;
  std::vector<std::uint32_t> next;  // per vertex: the next vertex of its ring
  PolygonIndexBuildOptions options;
  unsigned fork_levels;
};

// The candidate `c` of the parent cell (centre `from`), narrowed to `cell`; false when the
// polygon holds no point of the cell.
bool narrow(const Context& ctx, const Candidate& c, const Double2& from, const Box2d& cell,
            Candidate& out) {
  out.polygon = c.polygon;
  out.inside = c.inside;
  out.edges.clear();
  if (c.inside) return true;
  const auto v = ctx.layer.vertices;
  const Double2 centre = format::quadtree_centre(cell);
  out.centre = c.centre;
  for (const std::uint32_t a : c.edges) {
    const Double2& p = v[a];
    const Double2& q = v[ctx.next[a]];
    out.centre ^= shifted_segment_crosses(from, centre, p, q);
    if (segment_meets_box(p, q, cell.min, cell.max)) out.edges.push_back(a);
  }
  if (!out.edges.empty()) return true;
  out.inside = out.centre;  // no boundary in the closed cell: one answer for all of it
  return out.inside;
}

std::unique_ptr<TempNode> build_node(const Context& ctx, const std::vector<Candidate>& parent,
                                     const Double2& from, const Box2d& cell, std::uint32_t depth) {
  std::vector<Candidate> narrowed(parent.size());
  std::vector<char> keep(parent.size());
  parallel_for_batched(
      parent.size(), 64, depth < ctx.fork_levels ? ctx.options.threads : 1,
      [&](std::size_t i) { keep[i] = narrow(ctx, parent[i], from, cell, narrowed[i]); });
  auto node = std::make_unique<TempNode>();
  std::uint64_t edges = 0;
  for (std::size_t i = 0; i < parent.size(); ++i)
    if (keep[i]) {
      edges += narrowed[i].edges.size();
      node->entries.push_back(std::move(narrowed[i]));
    }
  if (edges <= ctx.options.max_edges || depth >= ctx.options.max_depth) return node;
  parallel_for(4, depth < ctx.fork_levels ? ctx.options.threads : 1, [&](std::size_t c) {
    node->children[c] = build_node(ctx, node->entries, format::quadtree_centre(cell),
                                   format::quadtree_child_box(cell, std::uint32_t(c)), depth + 1);
  });
  node->entries.clear();
  node->entries.shrink_to_fit();
  return node;
}

void emit_leaf(const Context& ctx, const TempNode& t, FlatPolygonIndex& out,
               format::PolygonIndexNode& node) {
  node.first = std::uint32_t(out.entries.size());
  node.count = std::uint32_t(t.entries.size());
  for (const Candidate& c : t.entries) {
    if (c.inside) {
      out.entries.push_back({c.polygon, 0, format::kPolygonWhollyInside});
      continue;
    }
    out.entries.push_back(
        {c.polygon, std::uint32_t(out.edges.size()),
         std::uint32_t(c.edges.size()) | (c.centre ? format::kPolygonCentreInside : 0u)});
    for (const std::uint32_t a : c.edges) out.edges.push_back({a, ctx.next[a]});
  }
  ++out.leaf_count;
}

// Writes the children of `t` (stored at `index`) as one group, then each child's descendants.
void emit_children(const Context& ctx, const TempNode& t, std::uint32_t index, std::uint32_t depth,
                   FlatPolygonIndex& out) {
  const auto group = std::uint32_t(out.nodes.size());
  out.nodes[index] = {group, format::kPolygonNodeInterior};
  out.nodes.resize(group + 4);
  for (std::uint32_t c = 0; c < 4; ++c) {
    const TempNode& child = *t.children[c];
    if (child.leaf()) {
      emit_leaf(ctx, child, out, out.nodes[group + c]);
      out.depth = std::max(out.depth, depth + 1);
    } else {
      emit_children(ctx, child, group + c, depth + 1, out);
    }
  }
}

}  // namespace

FlatPolygonIndex build_polygon_index(const PolygonLayerView& layer,
                                     const PolygonIndexBuildOptions& options) {
  if (layer.polygon_count() > 0xFFFFFFFEu || layer.vertices.size() > 0x7FFFFFFFu)
    throw std::invalid_argument("polygon-index: more than 2^32 - 2 polygons or 2^31 - 1 vertices");
  Context ctx{layer, std::vector<std::uint32_t>(layer.vertices.size()), options,
              fork_depth(options.threads)};
  std::vector<Candidate> all(layer.polygon_count());
  for (std::size_t p = 0; p < layer.polygon_count(); ++p) {
    all[p].polygon = std::uint32_t(p);
    for (auto r = layer.polygon_rings[p]; r < layer.polygon_rings[p + 1]; ++r) {
      const auto lo = layer.ring_vertices[r], hi = layer.ring_vertices[r + 1];
      for (auto i = lo; i < hi; ++i) {
        ctx.next[i] = std::uint32_t(i + 1 == hi ? lo : i + 1);
        all[p].edges.push_back(std::uint32_t(i));
      }
    }
  }
  FlatPolygonIndex out;
  out.bounds = layer.bounds;
  // The root's parent: a cell whose centre is the root's, so narrowing crosses nothing.
  const Double2 centre = format::quadtree_centre(out.bounds);
  parallel_for(all.size(), options.threads, [&](std::size_t p) {
    for (const std::uint32_t a : all[p].edges)
      all[p].centre ^= crosses_ray(layer.vertices[a], layer.vertices[ctx.next[a]], centre);
  });
  const auto root = build_node(ctx, all, centre, out.bounds, 0);
  out.nodes.resize(1);
  if (root->leaf())
    emit_leaf(ctx, *root, out, out.nodes[0]);
  else
    emit_children(ctx, *root, 0, 0, out);
  return out;
}

}  // namespace kiln
