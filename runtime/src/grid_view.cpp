// The grid views' structural checks, and their views of a blob's structure.
#include <cmath>
#include <string>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/grid.hpp"
#include "kiln/runtime/manifest.hpp"

namespace kiln {

namespace {

template <class F>
void check_resolution(const std::uint32_t res[3], const std::string& what, F&& fail) {
  for (int a = 0; a < 3; ++a)
    if (res[a] < 1 || res[a] > format::kGridMaxAxis)
      fail(what + " resolution " + std::to_string(res[a]) + " is outside 1.." +
           std::to_string(format::kGridMaxAxis));
  if (std::uint64_t(res[0]) * res[1] * res[2] > format::kGridMaxCells)
    fail(what + " has more than " + std::to_string(format::kGridMaxCells) + " cells");
}

template <class F>
void check_frame(const GridFrame& f, F&& fail) {
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(f.lo[a]) || !std::isfinite(f.hi[a]) || !(f.lo[a] < f.hi[a]) ||
        !std::isfinite(f.hi[a] - f.lo[a]))
      fail("the grid's box is empty, infinite or NaN on axis " + std::to_string(a));
  check_resolution(f.res, "the grid's", fail);
}

// Offsets: cells + 1, from 0, never decreasing, ending at the references; references naming
// stored triangles.
template <class F>
void check_lists(const GridLists& lists, std::uint64_t cells, std::size_t triangle_count,
                 F&& fail) {
  if (lists.offsets.size() != cells + 1)
    fail(std::to_string(lists.offsets.size()) + " cell offsets for " + std::to_string(cells) +
         " cells");
  if (lists.offsets[0] != 0) fail("the first cell does not start at reference 0");
  for (std::uint64_t c = 0; c < cells; ++c)
    if (lists.offsets[c + 1] < lists.offsets[c])
      fail("cell " + std::to_string(c) + " ends before it starts");
  if (lists.offsets[cells] != lists.refs.size())
    fail("the cells hold " + std::to_string(lists.offsets[cells]) + " references, not " +
         std::to_string(lists.refs.size()));
  for (std::size_t r = 0; r < lists.refs.size(); ++r)
    if (lists.refs[r] >= triangle_count)
      fail("reference " + std::to_string(r) + " names triangle " + std::to_string(lists.refs[r]) +
           " of " + std::to_string(triangle_count));
}

const schema::GridDesc& grid_desc(const Blob& blob, const std::string& name, std::uint8_t levels) {
  const StructureInfo* info = blob.structure(name);
  if (info == nullptr) blob.fail("has no structure '" + name + "'");
  const auto* d = structure_table(blob, *info).desc_as<schema::GridDesc>();
  const char* what = levels == 1 ? "uniform grid" : "two-level grid";
  if (d == nullptr || d->levels() != levels)
    blob.fail("structure '" + name + "' is a " + info->kind + ", not a " + what);
  return *d;
}

// The top frame as the description states it (Blob::open checked that the bounds exist).
GridFrame frame_of(const schema::GridDesc& d) {
  const auto& b = *d.bounds();
  return GridFrame{{b.min().x(), b.min().y(), b.min().z()},
                   {b.max().x(), b.max().y(), b.max().z()},
                   {d.res_x(), d.res_y(), d.res_z()}};
}

}  // namespace

GridView::GridView(const GridFrame& frame, GridLists lists,
                   std::span<const format::RayTriangle> triangles, const std::string& name)
    : frame_(frame), lists_(lists), triangles_(triangles) {
  auto fail = [&](const std::string& what) { throw BlobError(name + ": " + what); };
  check_frame(frame, fail);
  check_lists(lists, frame.cell_count(), triangles.size(), fail);
}

GridView GridView::from_blob(const Blob& blob, const std::string& name) {
  const auto& d = grid_desc(blob, name, 1);
  return GridView(
      frame_of(d),
      {blob.section_view<std::uint32_t>(d.offsets()), blob.section_view<std::uint32_t>(d.refs())},
      blob.section_view<format::RayTriangle>(d.triangles()), blob.name() + ": " + name);
}

NestedGridView::NestedGridView(const GridFrame& top, std::span<const format::LeafGrid> leaves,
                               GridLists lists, std::span<const format::RayTriangle> triangles,
                               const std::string& name)
    : top_(top), leaves_(leaves), lists_(lists), triangles_(triangles) {
  auto fail = [&](const std::string& what) { throw BlobError(name + ": " + what); };
  check_frame(top, fail);
  if (leaves.size() != top.cell_count())
    fail(std::to_string(leaves.size()) + " leaf grids for " + std::to_string(top.cell_count()) +
         " top cells");
  std::uint64_t cells = 0;
  for (std::size_t c = 0; c < leaves.size(); ++c) {
    const auto& leaf = leaves[c];
    const std::string what = "top cell " + std::to_string(c);
    if (leaf.first_cell != cells) fail(what + "'s grid does not follow the previous one");
    if (leaf.res[0] == 0 && leaf.res[1] == 0 && leaf.res[2] == 0) continue;
    check_resolution(leaf.res, what + "'s", fail);
    cells += std::uint64_t(leaf.res[0]) * leaf.res[1] * leaf.res[2];
    if (cells >= lists.offsets.size()) fail(what + "'s grid runs past the cell offsets");
  }
  check_lists(lists, cells, triangles.size(), fail);
}

NestedGridView NestedGridView::from_blob(const Blob& blob, const std::string& name) {
  const auto& d = grid_desc(blob, name, 2);
  return NestedGridView(
      frame_of(d), blob.section_view<format::LeafGrid>(d.leaves()),
      {blob.section_view<std::uint32_t>(d.offsets()), blob.section_view<std::uint32_t>(d.refs())},
      blob.section_view<format::RayTriangle>(d.triangles()), blob.name() + ": " + name);
}

}  // namespace kiln
