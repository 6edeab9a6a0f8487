// The polygon index as the compiler registers it: "polygon-index" over the input's polygon
// layer, its options, and its contribution to a blob: nodes, entries, edges, PolygonIndexDesc.
#include <cstdio>
#include <memory>

#include "kiln/compiler/polygon_index_builder.hpp"
#include "kiln/compiler/structure_builder.hpp"
#include "kiln/schema/manifest_generated.h"

namespace kiln {

extern const StructureBuilder kPolygonIndexBuilder;

namespace {

std::vector<StructureOption> polygon_index_options() {
  return {
      {"max-edges", "", "8", "Polygon index: a cell listing more edges splits", false,
       parse_uint_in(1, 1u << 20)},
      {"max-depth", "", "16", "Polygon index: deepest cell (root = 0)", false,
       parse_uint_in(0, format::kPolygonIndexMaxDepth)},
  };
}

BuiltStructure build(const Scene& scene, const StructureRequest& request, unsigned threads) {
  PolygonIndexBuildOptions options;
  options.max_edges = request.uint_option("max-edges");
  options.max_depth = request.uint_option("max-depth");
  options.threads = threads;
  auto index =
      std::make_shared<FlatPolygonIndex>(build_polygon_index(view_of(*scene.polygons), options));
  BuiltStructure built;
  built.sections = {raw_section(format::kSectionPolygonIndexNodes, index->nodes),
                    raw_section(format::kSectionPolygonIndexEntries, index->entries),
                    raw_section(format::kSectionPolygonIndexEdges, index->edges)};
  const std::uint64_t polygons = scene.polygons->polygon_count();
  const std::uint64_t vertices = scene.polygons->vertices.size();
  const FlatPolygonIndex* x = index.get();
  built.describe = [options, x, polygons, vertices](flatbuffers::FlatBufferBuilder& fbb,
                                                    std::span<const std::uint32_t> at) {
    const schema::Bounds2d bounds(schema::Vec2d(x->bounds.min.x, x->bounds.min.y),
                                  schema::Vec2d(x->bounds.max.x, x->bounds.max.y));
    const auto desc = schema::CreatePolygonIndexDesc(
        fbb, options.max_edges, options.max_depth, &bounds, at[0], at[1], at[2], x->nodes.size(),
        x->leaf_count, x->entries.size(), x->edges.size(), x->depth, polygons, vertices);
    return std::pair{std::uint8_t(schema::StructureDesc::PolygonIndexDesc), desc.o};
  };
  const double bytes = double(x->nodes.size() * 8 + x->entries.size() * 12 + x->edges.size() * 8);
  char line[256];
  std::snprintf(line, sizeof line,
                "%zu nodes (%llu leaves), depth %u, %zu entries, %zu edge refs, %.1f bytes/vertex",
                x->nodes.size(), (unsigned long long)x->leaf_count, x->depth, x->entries.size(),
                x->edges.size(), vertices ? bytes / double(vertices) : 0.0);
  built.summary = line;
  built.storage = std::move(index);
  return built;
}

}  // namespace

const StructureBuilder kPolygonIndexBuilder{"polygon-index",
                                            "quadtree over a polygon layer (point in polygon)",
                                            InputKind::kPolygons2, polygon_index_options(), build};

}  // namespace kiln
