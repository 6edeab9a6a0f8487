// The grids as the compiler registers them: "grid" (uniform) and "nested-grid" (two-level), their
// densities, and their contribution to a blob: cell offsets, references, triangles (and the leaf
// grids), one GridDesc.
#include <cstdio>

#include "kiln/compiler/grid_builder.hpp"
#include "kiln/compiler/structure_builder.hpp"
#include "kiln/schema/manifest_generated.h"

namespace kiln {

extern const StructureBuilder kGridBuilder, kNestedGridBuilder;

namespace {

std::string summary_of(const FlatGrid& g) {
  char line[256];
  std::snprintf(line, sizeof line,
                "%u x %u x %u %s, %llu cells (%llu empty), %.3f references/triangle, largest "
                "cell %u, %.1f bytes/triangle",
                g.frame.res[0], g.frame.res[1], g.frame.res[2],
                g.levels == 1 ? "cells" : "top cells", (unsigned long long)g.stats.cell_count,
                (unsigned long long)g.stats.empty_cell_count, g.stats.references_per_triangle,
                g.stats.largest_cell, g.stats.bytes_per_triangle);
  return line;
}

BuiltStructure built_of(std::shared_ptr<FlatGrid> grid, const GridBuildOptions& o) {
  BuiltStructure built;
  built.sections = {raw_section(format::kSectionGridOffsets, grid->offsets),
                    raw_section(format::kSectionGridRefs, grid->refs),
                    raw_section(format::kSectionGridTriangles, grid->triangles)};
  if (grid->levels == 2)
    built.sections.push_back(raw_section(format::kSectionGridLeaves, grid->leaves));
  const GridStatistics s = grid->stats;
  const GridFrame f = grid->frame;
  const std::uint8_t levels = grid->levels;
  built.describe = [o, s, f, levels](flatbuffers::FlatBufferBuilder& fbb,
                                     std::span<const std::uint32_t> index) {
    const schema::Bounds bounds(schema::Vec3(f.lo[0], f.lo[1], f.lo[2]),
                                schema::Vec3(f.hi[0], f.hi[1], f.hi[2]));
    const auto desc = schema::CreateGridDesc(
        fbb, levels, o.density, levels == 2 ? o.leaf_density : 0.0f, &bounds, f.res[0], f.res[1],
        f.res[2], index[0], index[1], index[2], levels == 2 ? index[3] : 0xFFFFFFFFu, s.cell_count,
        s.empty_cell_count, s.top_empty_cell_count, s.reference_count, s.largest_cell,
        s.references_per_triangle, s.bytes_per_triangle);
    return std::pair{std::uint8_t(schema::StructureDesc::GridDesc), desc.o};
  };
  built.summary = summary_of(*grid);
  built.storage = std::move(grid);
  return built;
}

BuiltStructure build_uniform(const Scene& scene, const StructureRequest& request,
                             unsigned threads) {
  GridBuildOptions options;
  options.density = request.float_option("density");
  options.threads = threads;
  return built_of(std::make_shared<FlatGrid>(build_grid(scene, options)), options);
}

BuiltStructure build_nested(const Scene& scene, const StructureRequest& request, unsigned threads) {
  GridBuildOptions options;
  options.density = request.float_option("density");
  options.leaf_density = request.float_option("leaf-density");
  options.threads = threads;
  return built_of(std::make_shared<FlatGrid>(build_nested_grid(scene, options)), options);
}

}  // namespace

const StructureBuilder kGridBuilder{
    "grid",
    "uniform grid over triangles, 3D-DDA traversal (Amanatides & Woo)",
    InputKind::kTriangles,
    {{"density", "--grid-density", "2", "uniform grid: about density x triangles cells", false,
      parse_float_in(0.001, 1000)}},
    build_uniform};

const StructureBuilder kNestedGridBuilder{
    "nested-grid",
    "two-level grid over triangles (Kalojanov, Billeter & Slusallek)",
    InputKind::kTriangles,
    {{"density", "--nested-grid-density", "0.0625",
      "two-level grid: about density x triangles top cells", false, parse_float_in(0.0001, 1000)},
     {"leaf-density", "--nested-grid-leaf-density", "2",
      "two-level grid: about leaf-density x n cells in a top cell of n triangles", false,
      parse_float_in(0.001, 1000)}},
    build_nested};

}  // namespace kiln
