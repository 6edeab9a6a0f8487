// The polygon index kind of the runtime registry ("polygon-index"): its manifest checks, view
// (point in polygon over the blob's polygon layer), deep check and description.
#include <algorithm>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/parallel.hpp"
#include "kiln/runtime/polygon_index.hpp"
#include "kiln/runtime/predicates2.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "text_format.hpp"

namespace kiln {

namespace {

constexpr std::uint32_t kSections[] = {format::kSectionPolygonIndexNodes,
                                       format::kSectionPolygonIndexEntries,
                                       format::kSectionPolygonIndexEdges};

class PolygonIndexStructure final : public StructureView, public PolygonQueries {
 public:
  explicit PolygonIndexStructure(PolygonIndexView view) : view_(std::move(view)) {}

  const PolygonQueries* polygons() const override { return this; }
  std::uint32_t locate(const format::Double2& p) const override { return view_.locate(p); }
  void locate_many(std::span<const format::Double2> points, std::span<std::uint32_t> out,
                   unsigned threads) const override {
    if (out.size() != points.size())
      throw std::invalid_argument("locate_many: " + std::to_string(out.size()) +
                                  " answer slots for " + std::to_string(points.size()) + " points");
    // Runs of kRun points, each through the view's pipelined batch call into its own slots.
    constexpr std::size_t kRun = 4096;
    parallel_for((points.size() + kRun - 1) / kRun, threads, [&](std::size_t b) {
      const std::size_t at = b * kRun, size = std::min(kRun, points.size() - at);
      view_.locate_many(points.subspan(at, size), out.subspan(at, size));
    });
  }
  std::uint32_t locate_counting(const format::Double2& p, Cost& cost) const override {
    return view_.locate_counting(p, cost);
  }
  void locate_all(const format::Double2& p, std::vector<std::uint32_t>& out) const override {
    view_.locate_all(p, out);
  }
  void features_in_box(const format::Box2d& box, std::vector<std::uint32_t>& out) const override {
    view_.features_in_box(box, out);
  }
  void cells(std::vector<IndexCell2>& out) const override { view_.cells(out); }

 private:
  PolygonIndexView view_;
};

void check(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::PolygonIndexDesc>(blob, info);
  const auto where = "structure '" + info.name + "' ";
  const PolygonLayerView layer = blob.polygon_layer();
  if (d.polygon_count() != layer.polygon_count() || d.vertex_count() != layer.vertices.size())
    blob.fail_section(0, where + "was built over another polygon layer");
  blob.check_section(where + "nodes", d.nodes(), format::kSectionPolygonIndexNodes,
                     sizeof(format::PolygonIndexNode), d.node_count(), false);
  blob.check_section(where + "entries", d.entries(), format::kSectionPolygonIndexEntries,
                     sizeof(format::PolygonIndexEntry), d.entry_count(), false);
  blob.check_section(where + "edges", d.edges(), format::kSectionPolygonIndexEdges,
                     sizeof(format::PolygonIndexEdge), d.edge_count(), false);
  if (d.node_count() == 0) blob.fail_section(0, where + "has no nodes");
  if (d.bounds() == nullptr) blob.fail_section(0, where + "has no bounds");
}

std::unique_ptr<StructureView> open(const Blob& blob, const StructureInfo& info) {
  return std::make_unique<PolygonIndexStructure>(PolygonIndexView::from_blob(blob, info.name));
}

// Beyond the view's walk: every listed edge is an edge of a ring of its entry's polygon (a
// vertex and the next one of the same ring), so the parities the queries compute are the
// polygon's.
void verify(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::PolygonIndexDesc>(blob, info);
  const PolygonIndexView view = PolygonIndexView::from_blob(blob, info.name);
  const auto& p = view.parts();
  for (std::size_t i = 0; i < p.entries.size(); ++i) {
    const auto& e = p.entries[i];
    if (e.wholly_inside()) continue;
    const std::uint64_t first_ring = p.layer.polygon_rings[e.polygon];
    const std::uint64_t last_ring = p.layer.polygon_rings[e.polygon + 1];
    const std::uint64_t lo = p.layer.ring_vertices[first_ring];
    const std::uint64_t hi = p.layer.ring_vertices[last_ring];
    for (const auto& edge : p.edges.subspan(e.first_edge, e.edges())) {
      bool ok = edge.a >= lo && edge.a < hi;
      if (ok) {
        // The ring holding edge.a: its next vertex wraps to the ring's first.
        const auto rings = p.layer.ring_vertices.subspan(first_ring, last_ring - first_ring + 1);
        const auto r = std::upper_bound(rings.begin(), rings.end(), std::uint64_t(edge.a)) - 1;
        const std::uint64_t next = edge.a + 1 == *(r + 1) ? *r : edge.a + 1;
        ok = edge.b == next;
      }
      if (!ok)
        blob.fail_section(d.edges(), info.name + " entry " + std::to_string(i) +
                                         " lists an edge that is not its polygon's");
    }
  }
}

Description describe(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::PolygonIndexDesc>(blob, info);
  const PolygonIndexView view = PolygonIndexView::from_blob(blob, info.name);
  const std::uint64_t bytes = d.node_count() * sizeof(format::PolygonIndexNode) +
                              d.entry_count() * sizeof(format::PolygonIndexEntry) +
                              d.edge_count() * sizeof(format::PolygonIndexEdge);
  const double per_vertex = d.vertex_count() ? double(bytes) / double(d.vertex_count()) : 0.0;
  Description out;
  out.lines.push_back(
      printf_string("quadtree, max %u edges per cell, max depth %u", d.max_edges(), d.max_depth()));
  out.lines.push_back(printf_string(
      "%llu nodes, %llu leaves, depth %u, %llu entries, %llu edge refs, %.1f bytes/vertex",
      (unsigned long long)d.node_count(), (unsigned long long)d.leaf_count(), d.depth(),
      (unsigned long long)d.entry_count(), (unsigned long long)d.edge_count(), per_vertex));
  DescTable table{
      "levels",
      {"level", "leaves", "interior", "boundary_leaves", "entries", "edges_per_boundary_leaf"},
      {}};
  const auto levels = view.levels();
  for (std::size_t l = 0; l < levels.size(); ++l) {
    const auto& v = levels[l];
    const double per = v.boundary_leaves ? double(v.edge_refs) / double(v.boundary_leaves) : 0.0;
    out.lines.push_back(
        printf_string("  level %zu: %llu leaves (%llu boundary, %.1f edges each), %llu interior", l,
                      (unsigned long long)v.leaves, (unsigned long long)v.boundary_leaves, per,
                      (unsigned long long)v.interior));
    table.rows.push_back(
        {std::uint64_t(l), v.leaves, v.interior, v.boundary_leaves, v.entries, per});
  }
  out.field("max_edges", d.max_edges()).field("max_depth", d.max_depth());
  out.field("node_count", d.node_count()).field("leaf_count", d.leaf_count());
  out.field("depth", d.depth()).field("entry_count", d.entry_count());
  out.field("edge_count", d.edge_count()).field("bytes", bytes);
  out.field("bytes_per_vertex", per_vertex);
  out.tables.push_back(std::move(table));
  return out;
}

}  // namespace

PolygonIndexView PolygonIndexView::from_blob(const Blob& blob, const std::string& name) {
  const StructureInfo* info = blob.structure(name);
  if (info == nullptr || info->kind != "polygon-index")
    blob.fail("has no polygon index named '" + name + "'");
  const auto& d = desc_of<schema::PolygonIndexDesc>(blob, *info);
  PolygonIndexParts parts;
  parts.layer = blob.polygon_layer();
  const auto* b = d.bounds();
  parts.bounds = {{b->min().x(), b->min().y()}, {b->max().x(), b->max().y()}};
  parts.nodes = blob.section_view<format::PolygonIndexNode>(d.nodes());
  parts.entries = blob.section_view<format::PolygonIndexEntry>(d.entries());
  parts.edges = blob.section_view<format::PolygonIndexEdge>(d.edges());
  try {
    return PolygonIndexView(parts, name);
  } catch (const BlobError& e) {
    blob.fail(e.what());
  }
}

extern const StructureKind kPolygonIndexKind;

const StructureKind kPolygonIndexKind{"polygon-index",
                                      "quadtree over a polygon layer: point in polygon",
                                      InputKind::kPolygons2,
                                      kSections,
                                      std::uint8_t(schema::StructureDesc::PolygonIndexDesc),
                                      check,
                                      open,
                                      verify,
                                      describe};

}  // namespace kiln
