// The k-d tree as the compiler registers it: "kdtree", its SAH constants, and its contribution
// to a blob: nodes, leaf primitive ids, triangles, KdTreeDesc.
#include <cstdio>

#include "kiln/compiler/kdtree_builder.hpp"
#include "kiln/compiler/structure_builder.hpp"
#include "kiln/schema/manifest_generated.h"

namespace kiln {

extern const StructureBuilder kKdTreeBuilder;

namespace {

std::vector<StructureOption> kdtree_options() {
  return {
      {"traversal-cost", "--kd-traversal-cost", "15", "k-d tree SAH node cost", false,
       parse_float_in(0, 1000)},
      {"intersection-cost", "--kd-intersection-cost", "20", "k-d tree SAH triangle cost", false,
       parse_float_in(0.001, 1000)},
      {"empty-bonus", "--kd-empty-bonus", "0.2",
       "k-d tree: fraction of the cost forgiven for cutting off empty space", false,
       parse_float_in(0, 0.99)},
  };
}

std::string summary_of(const KdTreeStatistics& s) {
  char line[256];
  std::snprintf(line, sizeof line,
                "%llu nodes (%llu leaves, %llu empty), depth %u of %u, SAH cost %.3f, %.3f "
                "references/triangle, %.1f bytes/triangle",
                (unsigned long long)s.node_count, (unsigned long long)s.leaf_count,
                (unsigned long long)s.empty_leaf_count, s.max_depth, s.depth_limit, s.sah_cost,
                s.references_per_triangle, s.bytes_per_triangle);
  return line;
}

BuiltStructure build(const Scene& scene, const StructureRequest& request, unsigned threads) {
  KdTreeBuildOptions options;
  options.traversal_cost = request.float_option("traversal-cost");
  options.intersection_cost = request.float_option("intersection-cost");
  options.empty_bonus = request.float_option("empty-bonus");
  options.threads = threads;
  auto tree = std::make_shared<FlatKdTree>(build_kdtree(scene, options));
  BuiltStructure built;
  built.sections = {raw_section(format::kSectionKdNodes, tree->nodes),
                    raw_section(format::kSectionKdPrimIds, tree->prim_ids),
                    raw_section(format::kSectionKdTriangles, tree->triangles)};
  const KdTreeStatistics s = tree->stats;
  const format::Box3f b = tree->bounds;
  built.describe = [o = options, s, b](flatbuffers::FlatBufferBuilder& fbb,
                                       std::span<const std::uint32_t> index) {
    const schema::Bounds bounds(schema::Vec3(b.min.x, b.min.y, b.min.z),
                                schema::Vec3(b.max.x, b.max.y, b.max.z));
    const auto desc = schema::CreateKdTreeDesc(
        fbb, o.traversal_cost, o.intersection_cost, o.empty_bonus, s.depth_limit, &bounds, index[0],
        index[1], index[2], s.node_count, s.leaf_count, s.empty_leaf_count, s.reference_count,
        s.max_depth, s.largest_leaf, s.references_per_triangle, s.sah_cost, s.bytes_per_triangle);
    return std::pair{std::uint8_t(schema::StructureDesc::KdTreeDesc), desc.o};
  };
  built.summary = summary_of(s);
  built.storage = std::move(tree);
  return built;
}

}  // namespace

const StructureBuilder kKdTreeBuilder{"kdtree", "SAH k-d tree over triangles (Wald & Havran)",
                                      InputKind::kTriangles, kdtree_options(), build};

}  // namespace kiln
