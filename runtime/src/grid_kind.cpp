// The grid kinds of the runtime registry: "grid" (uniform) and "nested-grid" (two-level), one
// GridDesc for both: their manifest checks, views, deep check and description.
#include <algorithm>
#include <cstring>
#include <memory>
#include <string>

#include "kiln/formats/grid.hpp"
#include "kiln/runtime/grid.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "kiln/runtime/triangle_geometry.hpp"
#include "text_format.hpp"
#include "triangle_structure.hpp"

namespace kiln {

namespace {

constexpr std::uint32_t kGridSections[] = {format::kSectionGridOffsets, format::kSectionGridRefs,
                                           format::kSectionGridTriangles};
constexpr std::uint32_t kNestedSections[] = {format::kSectionGridOffsets, format::kSectionGridRefs,
                                             format::kSectionGridTriangles,
                                             format::kSectionGridLeaves};

void check(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::GridDesc>(blob, info);
  const auto where = "structure '" + info.name + "' ";
  const std::uint8_t levels = info.kind == "grid" ? 1 : 2;
  if (d.levels() != levels)
    blob.fail_section(
        0, where + "has " + std::to_string(d.levels()) + " levels, not " + std::to_string(levels));
  if (d.bounds() == nullptr) blob.fail_section(0, where + "has no bounds");
  if (d.cell_count() >= 0xFFFFFFFFull) blob.fail_section(0, where + "has too many cells");
  blob.check_section(where + "cell offsets", d.offsets(), format::kSectionGridOffsets,
                     sizeof(std::uint32_t), d.cell_count() + 1, false);
  blob.check_section(where + "references", d.refs(), format::kSectionGridRefs,
                     sizeof(std::uint32_t), d.reference_count(), false);
  blob.check_section(where + "triangles", d.triangles(), format::kSectionGridTriangles,
                     sizeof(format::RayTriangle), blob.input().triangle_count, false);
  if (levels == 1) return;
  const std::uint32_t res[3] = {d.res_x(), d.res_y(), d.res_z()};
  for (const auto r : res)
    if (r < 1 || r > format::kGridMaxAxis) blob.fail_section(0, where + "has a bad resolution");
  blob.check_section(where + "leaf grids", d.leaves(), format::kSectionGridLeaves,
                     sizeof(format::LeafGrid), std::uint64_t(res[0]) * res[1] * res[2], false);
}

std::unique_ptr<StructureView> open(const Blob& blob, const StructureInfo& info) {
  if (info.kind == "grid")
    return std::make_unique<TriangleStructure<GridView>>(blob,
                                                         GridView::from_blob(blob, info.name));
  return std::make_unique<TriangleStructure<NestedGridView>>(
      blob, NestedGridView::from_blob(blob, info.name));
}

// Calls fn(cell) for every cell of `f` whose closed box triangle `t` meets (exact test); false
// when the triangle's bounds miss the grid.
template <class Fn>
bool cells_meeting(const GridFrame& f, const format::RayTriangle& t, Fn&& fn) {
  const format::Double3 v[3] = {to_d(t.v0), to_d(t.v1), to_d(t.v2)};
  std::uint32_t first[3], last[3];
  for (int a = 0; a < 3; ++a) {
    const double lo = std::min({at(v[0], a), at(v[1], a), at(v[2], a)});
    const double hi = std::max({at(v[0], a), at(v[1], a), at(v[2], a)});
    if (!cell_range(f, a, lo, hi, first[a], last[a])) return false;
  }
  std::uint32_t c[3];
  for (c[2] = first[2]; c[2] <= last[2]; ++c[2])
    for (c[1] = first[1]; c[1] <= last[1]; ++c[1])
      for (c[0] = first[0]; c[0] <= last[0]; ++c[0]) {
        const format::Double3 lo{f.plane(0, c[0]), f.plane(1, c[1]), f.plane(2, c[2])};
        const format::Double3 hi{f.plane(0, c[0] + 1), f.plane(1, c[1] + 1), f.plane(2, c[2] + 1)};
        if (triangle_overlaps_box(v[0], v[1], v[2], lo, hi)) fn(c);
      }
  return true;
}

// Every cell of `f` whose closed box triangle `prim` meets must list it (lists are sorted).
void check_cells(const Blob& blob, std::uint32_t section, const std::string& name,
                 const GridFrame& f, const GridLists& lists, std::uint64_t base,
                 const format::RayTriangle& t, std::uint32_t prim) {
  const bool inside = cells_meeting(f, t, [&](const std::uint32_t c[3]) {
    const auto refs = lists.cell(base + f.linear(c));
    if (!std::binary_search(refs.begin(), refs.end(), prim))
      blob.fail_section(
          section, name + " triangle " + std::to_string(prim) + " is missing from a cell it meets");
  });
  if (!inside)
    blob.fail_section(section, name + " triangle " + std::to_string(prim) + " is outside");
}

void verify_sorted(const Blob& blob, std::uint32_t section, const std::string& name,
                   const GridLists& lists) {
  for (std::size_t c = 0; c + 1 < lists.offsets.size(); ++c) {
    const auto refs = lists.cell(c);
    for (std::size_t i = 1; i < refs.size(); ++i)
      if (!(refs[i - 1] < refs[i]))
        blob.fail_section(section, name + " cell " + std::to_string(c) + " is not sorted");
  }
}

// Beyond the view's structural walk: the triangle copies, sorted lists, and every triangle
// listed in every cell (of every level) whose box it meets.
void verify(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::GridDesc>(blob, info);
  const std::string& name = info.name;
  if (info.kind == "grid") {
    const GridView g = GridView::from_blob(blob, name);
    verify_triangle_copies(blob, d.triangles(), name, g.triangles());
    verify_sorted(blob, d.refs(), name, g.lists());
    for (std::uint32_t i = 0; i < g.triangles().size(); ++i)
      check_cells(blob, d.refs(), name, g.frame(), g.lists(), 0, g.triangles()[i], i);
    return;
  }
  const NestedGridView g = NestedGridView::from_blob(blob, name);
  verify_triangle_copies(blob, d.triangles(), name, g.triangles());
  verify_sorted(blob, d.refs(), name, g.lists());
  const GridFrame& top = g.frame();
  for (std::uint32_t i = 0; i < g.triangles().size(); ++i) {
    const auto& t = g.triangles()[i];
    const bool inside = cells_meeting(top, t, [&](const std::uint32_t c[3]) {
      const format::LeafGrid& leaf = g.leaves()[top.linear(c)];
      if (leaf.res[0] == 0)
        blob.fail_section(d.leaves(), name + " triangle " + std::to_string(i) +
                                          " meets a top cell without a grid");
      check_cells(blob, d.refs(), name, g.leaf_frame(c), g.lists(), leaf.first_cell, t, i);
    });
    if (!inside)
      blob.fail_section(d.refs(), name + " triangle " + std::to_string(i) + " is outside");
  }
}

Description describe(const Blob& blob, const StructureInfo& info) {
  const auto& g = desc_of<schema::GridDesc>(blob, info);
  Description out;
  const unsigned long long cells = g.cell_count(),
                           top = std::uint64_t(g.res_x()) * g.res_y() * g.res_z();
  if (g.levels() == 1)
    out.lines.push_back(printf_string(
        "resolution %u x %u x %u (density %g): %llu cells, %llu empty", g.res_x(), g.res_y(),
        g.res_z(), double(g.density()), cells, (unsigned long long)g.empty_cell_count()));
  else
    out.lines.push_back(printf_string(
        "top %u x %u x %u (density %g): %llu cells, %llu without a grid; leaf density %g: %llu "
        "leaf cells, %llu empty",
        g.res_x(), g.res_y(), g.res_z(), double(g.density()), top,
        (unsigned long long)g.top_empty_cell_count(), double(g.leaf_density()), cells,
        (unsigned long long)g.empty_cell_count()));
  out.lines.push_back(
      printf_string("%llu references (%.3f per triangle), largest cell %u, %.1f bytes/triangle",
                    (unsigned long long)g.reference_count(), g.references_per_triangle(),
                    g.largest_cell(), g.bytes_per_triangle()));
  out.field("levels", g.levels()).field("density", g.density());
  if (g.levels() == 2) out.field("leaf_density", g.leaf_density());
  out.field("res_x", g.res_x()).field("res_y", g.res_y()).field("res_z", g.res_z());
  out.field("cell_count", g.cell_count()).field("empty_cell_count", g.empty_cell_count());
  if (g.levels() == 2) out.field("top_empty_cell_count", g.top_empty_cell_count());
  out.field("reference_count", g.reference_count()).field("largest_cell", g.largest_cell());
  out.field("references_per_triangle", g.references_per_triangle());
  out.field("bytes_per_triangle", g.bytes_per_triangle());
  return out;
}

}  // namespace

extern const StructureKind kGridKind, kNestedGridKind;

const StructureKind kGridKind{"grid",
                              "uniform grid (3D-DDA): rays, closest point, inside, box",
                              InputKind::kTriangles,
                              kGridSections,
                              std::uint8_t(schema::StructureDesc::GridDesc),
                              check,
                              open,
                              verify,
                              describe};

const StructureKind kNestedGridKind{"nested-grid",
                                    "two-level grid (Kalojanov et al. 2011): rays, closest "
                                    "point, inside, box",
                                    InputKind::kTriangles,
                                    kNestedSections,
                                    std::uint8_t(schema::StructureDesc::GridDesc),
                                    check,
                                    open,
                                    verify,
                                    describe};

}  // namespace kiln
