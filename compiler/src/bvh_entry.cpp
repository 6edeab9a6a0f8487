// The BVH family's contribution to a blob: nodes, leaf triangles, primitive ids, BvhDesc.
#include <cstdio>

#include "accel_entry.hpp"
#include "kiln/formats/bvh.hpp"

namespace kiln {

AccelEntry make_bvh_entry(const Scene& scene, const AccelRequest& request, unsigned threads) {
  BvhBuildOptions options = request.bvh;
  options.threads = threads;
  auto flat = std::make_shared<FlatBvh>(build_bvh(scene, options));
  AccelEntry entry;
  entry.sections = {raw_section(format::kSectionBvhNodes, flat->nodes),
                    raw_section(format::kSectionBvhTriangles, flat->triangles),
                    raw_section(format::kSectionBvhPrimIds, flat->prim_ids)};
  const BvhStatistics s = flat->stats;
  entry.describe = [kind = request.kind, o = options, s](flatbuffers::FlatBufferBuilder& fbb,
                                                         std::span<const std::uint32_t> index) {
    const auto desc = schema::CreateBvhDescDirect(
        fbb, bvh_builder_name(o.builder), o.bins, o.traversal_cost, o.intersection_cost,
        o.max_leaf_size, o.sbvh_alpha, o.sbvh_max_duplication, index[0], index[1], index[2],
        s.node_count, s.leaf_count, s.reference_count, s.max_depth, s.max_leaf_size,
        s.average_leaf_size, s.duplication_factor, s.sah_cost, s.bytes_per_triangle);
    const std::vector<std::uint32_t> owned(index.begin(), index.end());
    return schema::CreateAccelerationDirect(fbb, kind.c_str(), &owned, desc);
  };
  char line[256];
  std::snprintf(line, sizeof line,
                "%llu nodes, depth %u, SAH cost %.3f, %.3f references/triangle, %.1f "
                "bytes/triangle",
                (unsigned long long)s.node_count, s.max_depth, s.sah_cost, s.duplication_factor,
                s.bytes_per_triangle);
  entry.summary = line;
  entry.storage = std::move(flat);
  return entry;
}

}  // namespace kiln
