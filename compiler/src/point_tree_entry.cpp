// The point k-d tree as the compiler registers it: "points" over the input's 3D points (a point
// cloud, or a triangle scene's vertices), its options, and its contribution to a blob: nodes,
// points, ids, PointTreeDesc.
#include <cstdio>

#include "kiln/compiler/point_tree_builder.hpp"
#include "kiln/compiler/structure_builder.hpp"
#include "kiln/schema/manifest_generated.h"

namespace kiln {

extern const StructureBuilder kPointTreeBuilder;

namespace {

std::vector<StructureOption> point_tree_options() {
  return {
      {"split", "--points-split", "sliding-midpoint",
       "Point k-d tree cut: median (balanced) or sliding-midpoint (fat cells)", false,
       parse_one_of({"median", "sliding-midpoint"})},
      {"leaf-size", "--points-leaf-size", "10", "Point k-d tree: most points per leaf", false,
       parse_uint_in(1, kMaxPointLeafSize)},
  };
}

std::string summary_of(const PointTreeStatistics& s, PointSplitRule split) {
  char line[256];
  std::snprintf(line, sizeof line,
                "%llu points, %llu nodes (%llu leaves, largest %u), depth %u, %s, %.1f "
                "bytes/point",
                (unsigned long long)s.point_count, (unsigned long long)s.node_count,
                (unsigned long long)s.leaf_count, s.largest_leaf, s.max_depth,
                to_string(split).c_str(), s.bytes_per_point);
  return line;
}

BuiltStructure build(const Scene& scene, const StructureRequest& request, unsigned threads) {
  PointTreeBuildOptions options;
  options.split = request.text_option("split") == "median" ? PointSplitRule::kMedian
                                                           : PointSplitRule::kSlidingMidpoint;
  options.max_leaf_size = request.uint_option("leaf-size");
  options.threads = threads;
  auto tree = std::make_shared<FlatPointTree>(build_point_tree(scene.positions, options));
  BuiltStructure built;
  built.sections = {raw_section(format::kSectionPointNodes, tree->nodes),
                    raw_section(format::kSectionPointPositions, tree->points),
                    raw_section(format::kSectionPointIds, tree->ids)};
  const PointTreeStatistics s = tree->stats;
  const format::Box3f b = tree->bounds;
  built.describe = [o = options, s, b](flatbuffers::FlatBufferBuilder& fbb,
                                       std::span<const std::uint32_t> index) {
    const schema::Bounds bounds(schema::Vec3(b.min.x, b.min.y, b.min.z),
                                schema::Vec3(b.max.x, b.max.y, b.max.z));
    const auto desc = schema::CreatePointTreeDescDirect(
        fbb, to_string(o.split).c_str(), o.max_leaf_size, &bounds, index[0], index[1], index[2],
        s.node_count, s.leaf_count, s.point_count, s.max_depth, s.largest_leaf, s.bytes_per_point);
    return std::pair{std::uint8_t(schema::StructureDesc::PointTreeDesc), desc.o};
  };
  built.summary = summary_of(s, options.split);
  built.storage = std::move(tree);
  return built;
}

}  // namespace

const StructureBuilder kPointTreeBuilder{"points", "k-d tree over 3D points (kNN and radius)",
                                         InputKind::kPoint3, point_tree_options(), build};

}  // namespace kiln
