// The k-d tree's contribution to a blob: nodes, leaf primitive ids, triangles, KdTreeDesc.
#include <cstdio>

#include "accel_entry.hpp"
#include "kiln/compiler/kdtree_builder.hpp"

namespace kiln {

AccelEntry make_kdtree_entry(const Scene& scene, const AccelRequest& request, unsigned threads) {
  KdTreeBuildOptions options = request.kdtree;
  options.threads = threads;
  auto tree = std::make_shared<FlatKdTree>(build_kdtree(scene, options));
  AccelEntry entry;
  entry.sections = {raw_section(format::kSectionKdNodes, tree->nodes),
                    raw_section(format::kSectionKdPrimIds, tree->prim_ids),
                    raw_section(format::kSectionKdTriangles, tree->triangles)};
  const KdTreeStatistics s = tree->stats;
  const Aabb b = tree->bounds;
  entry.describe = [kind = request.kind, o = options, s, b](flatbuffers::FlatBufferBuilder& fbb,
                                                            std::span<const std::uint32_t> index) {
    const schema::Bounds bounds(schema::Vec3(b.lo[0], b.lo[1], b.lo[2]),
                                schema::Vec3(b.hi[0], b.hi[1], b.hi[2]));
    const auto desc = schema::CreateKdTreeDesc(
        fbb, o.traversal_cost, o.intersection_cost, o.empty_bonus, s.depth_limit, &bounds, index[0],
        index[1], index[2], s.node_count, s.leaf_count, s.empty_leaf_count, s.reference_count,
        s.max_depth, s.largest_leaf, s.references_per_triangle, s.sah_cost, s.bytes_per_triangle);
    const std::vector<std::uint32_t> owned(index.begin(), index.end());
    return schema::CreateAccelerationDirect(fbb, kind.c_str(), &owned, 0, desc);
  };
  char line[256];
  std::snprintf(line, sizeof line,
                "%llu nodes (%llu leaves, %llu empty), depth %u of %u, SAH cost %.3f, %.3f "
                "references/triangle, %.1f bytes/triangle",
                (unsigned long long)s.node_count, (unsigned long long)s.leaf_count,
                (unsigned long long)s.empty_leaf_count, s.max_depth, s.depth_limit, s.sah_cost,
                s.references_per_triangle, s.bytes_per_triangle);
  entry.summary = line;
  entry.storage = std::move(tree);
  return entry;
}

}  // namespace kiln
