// pbrt-style flattening: pre-order, first child adjacent, second child's index stored.
#include <algorithm>

#include "kiln/compiler/bvh_builder.hpp"

namespace kiln {

namespace {

struct Flattener {
  const Scene& scene;
  FlatBvh& out;

  std::uint32_t emit(const BvhBuildNode& n, std::uint32_t depth) {
    const auto index = std::uint32_t(out.nodes.size());
    out.nodes.emplace_back();
    auto& stats = out.stats;
    stats.max_depth = std::max(stats.max_depth, depth);
    format::BvhNode node{};
    for (int a = 0; a < 3; ++a)
      node.min[a] = format::at(n.box.min, a), node.max[a] = format::at(n.box.max, a);
    if (n.is_leaf()) {
      node.offset = std::uint32_t(out.triangles.size());
      node.count = std::uint16_t(n.prims.size());
      for (const std::uint32_t prim : n.prims) {
        const auto& t = scene.triangles[prim];
        out.triangles.push_back(
            {scene.positions[t.v[0]], scene.positions[t.v[1]], scene.positions[t.v[2]]});
        out.prim_ids.push_back(prim);
      }
      stats.leaf_count += 1;
      stats.max_leaf_size =
          std::max<std::uint32_t>(stats.max_leaf_size, std::uint32_t(n.prims.size()));
    } else {
      node.axis = n.axis;
      emit(*n.child[0], depth + 1);
      node.offset = emit(*n.child[1], depth + 1);
    }
    out.nodes[index] = node;
    return index;
  }
};

}  // namespace

FlatBvh flatten_bvh(const BvhBuildNode& root, const Scene& scene, const BvhBuildOptions& options) {
  FlatBvh out;
  Flattener{scene, out}.emit(root, 1);
  auto& s = out.stats;
  s.node_count = out.nodes.size();
  s.reference_count = out.prim_ids.size();
  s.average_leaf_size = s.leaf_count ? double(s.reference_count) / double(s.leaf_count) : 0;
  const double triangles = double(scene.triangles.size());
  s.duplication_factor = double(s.reference_count) / triangles;
  s.sah_cost = bvh_sah_cost(root, options);
  s.bytes_per_triangle = double(out.nodes.size() * sizeof(format::BvhNode) +
                                out.triangles.size() * sizeof(format::RayTriangle) +
                                out.prim_ids.size() * sizeof(std::uint32_t)) /
                         triangles;
  return out;
}

}  // namespace kiln
