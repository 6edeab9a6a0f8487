// The quadtree as the compiler registers it: "quadtree" over a 2D point table, its options, and
// its contribution to a blob: nodes, points in leaf order, ids, QuadtreeDesc.
#include <cstdio>
#include <stdexcept>

#include "kiln/compiler/quadtree_builder.hpp"
#include "kiln/compiler/structure_builder.hpp"
#include "kiln/schema/manifest_generated.h"

namespace kiln {

extern const StructureBuilder kQuadtreeBuilder;

namespace {

std::vector<StructureOption> quadtree_options() {
  return {
      {"bucket-size", "--quadtree-bucket-size", "32",
       "Quadtree: most points per leaf (except at max-depth or for coincident points)", false,
       parse_uint_in(1, kMaxQuadBucketSize)},
      {"max-depth", "--quadtree-max-depth", "32",
       "Quadtree: deepest leaf level (root = 0); closer points share a leaf", false,
       parse_uint_in(0, format::kQuadMaxDepth)},
  };
}

std::string summary_of(const QuadtreeStatistics& s, const QuadtreeBuildOptions& o) {
  char line[256];
  std::snprintf(line, sizeof line,
                "%llu points, %llu nodes (%llu leaves, largest bucket %u), depth %u, bucket "
                "size %u, %.1f bytes/point",
                (unsigned long long)s.point_count, (unsigned long long)s.node_count,
                (unsigned long long)s.leaf_count, s.largest_bucket, s.depth, o.bucket_size,
                s.bytes_per_point);
  return line;
}

schema::Bounds2d bounds_of(const format::Box2d& b) {
  return schema::Bounds2d(schema::Vec2d(b.min.x, b.min.y), schema::Vec2d(b.max.x, b.max.y));
}

BuiltStructure build(const Scene& scene, const StructureRequest& request, unsigned threads) {
  if (!scene.points2) throw std::invalid_argument("quadtree needs a 2D point table");
  QuadtreeBuildOptions options;
  options.bucket_size = request.uint_option("bucket-size");
  options.max_depth = request.uint_option("max-depth");
  options.threads = threads;
  auto tree = std::make_shared<FlatQuadtree>(build_quadtree(scene.points2->points, options));
  BuiltStructure built;
  built.sections = {raw_section(format::kSectionQuadNodes, tree->nodes),
                    raw_section(format::kSectionQuadPoints, tree->points),
                    raw_section(format::kSectionQuadIds, tree->ids)};
  const QuadtreeStatistics s = tree->stats;
  const format::Box2d root = tree->root, bounds = tree->bounds;
  built.describe = [o = options, s, root, bounds](flatbuffers::FlatBufferBuilder& fbb,
                                                  std::span<const std::uint32_t> index) {
    const schema::Bounds2d r = bounds_of(root), b = bounds_of(bounds);
    const auto desc = schema::CreateQuadtreeDesc(
        fbb, o.bucket_size, o.max_depth, &r, &b, index[0], index[1], index[2], s.node_count,
        s.leaf_count, s.point_count, s.depth, s.largest_bucket, s.bytes_per_point);
    return std::pair{std::uint8_t(schema::StructureDesc::QuadtreeDesc), desc.o};
  };
  built.summary = summary_of(s, options);
  built.storage = std::move(tree);
  return built;
}

}  // namespace

const StructureBuilder kQuadtreeBuilder{
    "quadtree", "bucket PR quadtree over 2D points (range, knn2d, radius2d)", InputKind::kPoint2,
    quadtree_options(), build};

}  // namespace kiln
