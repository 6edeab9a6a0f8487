// The BVH view's structural check, and its view of a blob's structure.
#include "kiln/runtime/bvh.hpp"

#include <string>
#include <vector>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/manifest.hpp"

namespace kiln {

BvhView::BvhView(std::span<const format::BvhNode> nodes,
                 std::span<const format::RayTriangle> triangles,
                 std::span<const std::uint32_t> prim_ids, const std::string& name)
    : nodes_(nodes), triangles_(triangles), prim_ids_(prim_ids) {
  auto fail = [&](const std::string& what) { throw BlobError(name + ": " + what); };
  if (nodes.empty()) fail("no nodes");
  if (triangles.size() != prim_ids.size())
    fail(std::to_string(triangles.size()) + " leaf triangles but " +
         std::to_string(prim_ids.size()) + " primitive ids");
  // Pre-order walk: the n-th node reached must be node n. That alone rules out sharing, cycles
  // and unreachable nodes; leaves must consume the references in order.
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
    if (p.depth > format::kBvhMaxDepth) fail("deeper than " + std::to_string(format::kBvhMaxDepth));
    const format::BvhNode& n = nodes[p.node];
    next_node += 1;
    if (n.count > 0) {
      if (n.offset != next_ref || n.count > triangles.size() - next_ref)
        fail("leaf " + std::to_string(p.node) + " has references out of order or out of range");
      next_ref += n.count;
      continue;
    }
    if (n.axis > 2)
      fail("node " + std::to_string(p.node) + " has split axis " + std::to_string(n.axis));
    if (n.offset <= p.node + 1u || n.offset >= nodes.size())
      fail("node " + std::to_string(p.node) + " has child index " + std::to_string(n.offset) +
           " out of range");
    if (p.node + 1u >= nodes.size()) fail("node " + std::to_string(p.node) + " has no first child");
    stack.push_back({n.offset, p.depth + 1});
    stack.push_back({p.node + 1, p.depth + 1});
  }
  if (next_node != nodes.size())
    fail(std::to_string(nodes.size() - next_node) + " nodes are unreachable");
  if (next_ref != triangles.size())
    fail(std::to_string(triangles.size() - next_ref) + " references are in no leaf");
}

BvhView BvhView::from_blob(const Blob& blob, const std::string& name) {
  const StructureInfo* info = blob.structure(name);
  if (info == nullptr) blob.fail("has no structure '" + name + "'");
  const auto* d = structure_table(blob, *info).desc_as<schema::BvhDesc>();
  if (d == nullptr) blob.fail("structure '" + name + "' is a " + info->kind + ", not a BVH");
  if (d->width() != 2)
    blob.fail("structure '" + name + "' is a " + std::to_string(d->width()) +
              "-wide BVH: open it with BvhWideView or open_structure");
  // Blob::open checked kinds, sizes and counts of these sections.
  return BvhView(blob.section_view<format::BvhNode>(d->nodes()),
                 blob.section_view<format::RayTriangle>(d->triangles()),
                 blob.section_view<std::uint32_t>(d->prim_ids()), blob.name() + ": " + name);
}

}  // namespace kiln
