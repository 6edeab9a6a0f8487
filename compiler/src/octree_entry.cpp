// The octree as the compiler registers it: "octree", its leaf size and depth limit, and its
// contribution to a blob: nodes, leaf primitive ids, triangles, OctreeDesc.
#include <cstdio>

#include "kiln/compiler/octree_builder.hpp"
#include "kiln/compiler/structure_builder.hpp"
#include "kiln/schema/manifest_generated.h"

namespace kiln {

extern const StructureBuilder kOctreeBuilder;

namespace {

std::vector<StructureOption> octree_options() {
  return {
      {"leaf-size", "--octree-leaf-size", "8",
       "octree: a cell with at most this many triangles is a leaf", false, parse_uint_in(1, 1024)},
      {"max-depth", "--octree-max-depth", "16", "octree: depth limit (root = 0)", false,
       parse_uint_in(1, format::kOctreeMaxDepth)},
      {"reference-budget", "--octree-reference-budget", "32",
       "octree: at most this many references per triangle (a level past it stays unsplit)", false,
       parse_uint_in(1, 4096)},
  };
}

std::string summary_of(const OctreeStatistics& s, const OctreeBuildOptions& o) {
  char line[256];
  std::snprintf(line, sizeof line,
                "%llu nodes (%llu leaves, %llu empty cells), depth %u of %u, largest leaf %u, "
                "%.3f references/triangle%s, %.1f bytes/triangle",
                (unsigned long long)s.node_count, (unsigned long long)s.leaf_count,
                (unsigned long long)s.empty_cell_count, s.max_depth, o.max_depth, s.largest_leaf,
                s.references_per_triangle, s.budget_reached ? " (budget reached)" : "",
                s.bytes_per_triangle);
  return line;
}

BuiltStructure build(const Scene& scene, const StructureRequest& request, unsigned threads) {
  OctreeBuildOptions options;
  options.leaf_size = request.uint_option("leaf-size");
  options.max_depth = request.uint_option("max-depth");
  options.reference_budget = request.uint_option("reference-budget");
  options.threads = threads;
  auto tree = std::make_shared<FlatOctree>(build_octree(scene, options));
  BuiltStructure built;
  built.sections = {raw_section(format::kSectionOctreeNodes, tree->nodes),
                    raw_section(format::kSectionOctreePrimIds, tree->prim_ids),
                    raw_section(format::kSectionOctreeTriangles, tree->triangles)};
  const OctreeStatistics s = tree->stats;
  const format::Box3f b = tree->bounds;
  built.describe = [o = options, s, b](flatbuffers::FlatBufferBuilder& fbb,
                                       std::span<const std::uint32_t> index) {
    const schema::Bounds bounds(schema::Vec3(b.min.x, b.min.y, b.min.z),
                                schema::Vec3(b.max.x, b.max.y, b.max.z));
    const auto desc = schema::CreateOctreeDesc(
        fbb, o.leaf_size, o.max_depth, &bounds, index[0], index[1], index[2], s.node_count,
        s.leaf_count, s.empty_cell_count, s.reference_count, s.max_depth, s.largest_leaf,
        s.depth_limited_leaves, s.stalled_leaves, s.references_per_triangle, s.bytes_per_triangle,
        o.reference_budget, s.budget_reached);
    return std::pair{std::uint8_t(schema::StructureDesc::OctreeDesc), desc.o};
  };
  built.summary = summary_of(s, options);
  built.storage = std::move(tree);
  return built;
}

}  // namespace

const StructureBuilder kOctreeBuilder{
    "octree", "octree over triangles, cells split at their centre (front-to-back traversal)",
    InputKind::kTriangles, octree_options(), build};

}  // namespace kiln
