#include <string>
#include <vector>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/kdtree.hpp"

namespace kiln {

KdTreeView::KdTreeView(std::span<const format::KdNode> nodes,
                       std::span<const std::uint32_t> prim_ids,
                       std::span<const format::BvhTriangle> triangles, const float bounds_min[3],
                       const float bounds_max[3], const std::string& name)
    : nodes_(nodes), prim_ids_(prim_ids), triangles_(triangles) {
  auto fail = [&](const std::string& what) { throw BlobError(name + ": " + what); };
  for (int a = 0; a < 3; ++a) min_[a] = bounds_min[a], max_[a] = bounds_max[a];
  if (nodes.empty()) fail("no nodes");
  // Pre-order walk: the n-th node reached must be node n, which rules out sharing, cycles and
  // unreachable nodes; leaves must consume the references in order.
  struct Pending {
    std::uint32_t node, depth;
  };
  std::vector<Pending> stack{{0, 1}};
  std::uint64_t next_node = 0, next_ref = 0;
  while (!stack.empty()) {
    const Pending p = stack.back();
    stack.pop_back();
    if (p.node != next_node)
      fail("node " + std::to_string(next_node) + " is not where depth-first order puts it");
    if (p.depth > format::kKdMaxDepth) fail("deeper than " + std::to_string(format::kKdMaxDepth));
    const format::KdNode& n = nodes[p.node];
    next_node += 1;
    if (n.is_leaf()) {
      if (n.first_reference() != next_ref || n.reference_count() > prim_ids.size() - next_ref)
        fail("leaf " + std::to_string(p.node) + " has references out of order or out of range");
      next_ref += n.reference_count();
      continue;
    }
    if (n.above_child() <= p.node + 1u || n.above_child() >= nodes.size())
      fail("node " + std::to_string(p.node) + " has child index " +
           std::to_string(n.above_child()) + " out of range");
    stack.push_back({n.above_child(), p.depth + 1});
    stack.push_back({p.node + 1, p.depth + 1});
  }
  if (next_node != nodes.size())
    fail(std::to_string(nodes.size() - next_node) + " nodes are unreachable");
  if (next_ref != prim_ids.size())
    fail(std::to_string(prim_ids.size() - next_ref) + " references are in no leaf");
  for (std::size_t r = 0; r < prim_ids.size(); ++r)
    if (prim_ids[r] >= triangles.size())
      fail("reference " + std::to_string(r) + " names triangle " + std::to_string(prim_ids[r]) +
           " of " + std::to_string(triangles.size()));
}

KdTreeView KdTreeView::from_blob(const Blob& blob, const std::string& name) {
  if (const auto* accels = blob.manifest().accelerations())
    for (const auto* accel : *accels)
      if (accel->kind()->str() == name && accel->kdtree() != nullptr) {
        // open() checked kinds, sizes and counts of these sections.
        const auto* d = accel->kdtree();
        const auto* b = d->bounds();
        const float lo[3] = {b ? b->min().x() : 0, b ? b->min().y() : 0, b ? b->min().z() : 0};
        const float hi[3] = {b ? b->max().x() : 0, b ? b->max().y() : 0, b ? b->max().z() : 0};
        return KdTreeView(blob.section_view<format::KdNode>(d->nodes()),
                          blob.section_view<std::uint32_t>(d->prim_ids()),
                          blob.section_view<format::BvhTriangle>(d->triangles()), lo, hi,
                          blob.name() + ": " + name);
      }
  throw BlobError(blob.name() + ": has no k-d tree '" + name + "'");
}

}  // namespace kiln
