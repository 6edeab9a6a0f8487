// The point k-d tree's contribution to a blob: nodes, points, ids, PointTreeDesc.
#include <cstdio>

#include "accel_entry.hpp"
#include "kiln/compiler/point_tree_builder.hpp"

namespace kiln {

AccelEntry make_point_tree_entry(const Scene& scene, const AccelRequest& request,
                                 unsigned threads) {
  PointTreeBuildOptions options = request.points;
  options.threads = threads;
  auto tree = std::make_shared<FlatPointTree>(build_point_tree(scene.positions, options));
  AccelEntry entry;
  entry.sections = {raw_section(format::kSectionPointNodes, tree->nodes),
                    raw_section(format::kSectionPointPositions, tree->points),
                    raw_section(format::kSectionPointIds, tree->ids)};
  const PointTreeStatistics s = tree->stats;
  const Aabb b = tree->bounds;
  entry.describe = [kind = request.kind, o = options, s, b](flatbuffers::FlatBufferBuilder& fbb,
                                                            std::span<const std::uint32_t> index) {
    const schema::Bounds bounds(schema::Vec3(b.lo[0], b.lo[1], b.lo[2]),
                                schema::Vec3(b.hi[0], b.hi[1], b.hi[2]));
    const auto desc = schema::CreatePointTreeDescDirect(
        fbb, to_string(o.split).c_str(), o.max_leaf_size, &bounds, index[0], index[1], index[2],
        s.node_count, s.leaf_count, s.point_count, s.max_depth, s.largest_leaf, s.bytes_per_point);
    const std::vector<std::uint32_t> owned(index.begin(), index.end());
    return schema::CreateAccelerationDirect(fbb, kind.c_str(), &owned, 0, 0, desc);
  };
  char line[256];
  std::snprintf(line, sizeof line,
                "%llu points, %llu nodes (%llu leaves, largest %u), depth %u, %s, %.1f "
                "bytes/point",
                (unsigned long long)s.point_count, (unsigned long long)s.node_count,
                (unsigned long long)s.leaf_count, s.largest_leaf, s.max_depth,
                to_string(options.split).c_str(), s.bytes_per_point);
  entry.summary = line;
  entry.storage = std::move(tree);
  return entry;
}

}  // namespace kiln
