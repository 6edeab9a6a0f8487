// The octree view's structural check, and its view of a blob's structure.
#include <bit>
#include <cmath>
#include <string>
#include <vector>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/octree.hpp"

namespace kiln {

namespace {

// One pass in index order: breadth-first order hands out child slots in the order nodes are
// met, so node i's children must start at the next free slot; since they lie after i, every
// parent is checked before its children, which is what lets depths be computed on the way.
// Leaves' reference ranges must follow each other from 0 and cover every reference. Returns
// the deepest node's depth.
template <class Fail>
std::uint32_t check_breadth_first(std::span<const format::OctreeNode> nodes,
                                  std::uint64_t reference_count, Fail fail) {
  if (nodes.empty()) fail("has no nodes");
  std::vector<std::uint8_t> depth(nodes.size(), 0);
  std::uint64_t next_node = 1, next_reference = 0;
  std::uint32_t deepest = 0;
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    if (i >= next_node) fail("node " + std::to_string(i) + " is the child of no node");
    const format::OctreeNode& n = nodes[i];
    if (n.is_leaf()) {
      if (n.first_reference() != next_reference ||
          n.reference_count() > reference_count - next_reference)
        fail("leaf " + std::to_string(i) + " has references out of order or out of range");
      next_reference += n.reference_count();
      continue;
    }
    if (n.bits >> 8 != 0) fail("interior node " + std::to_string(i) + " has reserved bits set");
    const auto count = std::uint64_t(std::popcount(n.child_mask()));
    if (n.first_child() != next_node || count > nodes.size() - next_node)
      fail("node " + std::to_string(i) + " has children out of order or out of range");
    if (depth[i] + 1u > format::kOctreeMaxDepth)
      fail("deeper than " + std::to_string(format::kOctreeMaxDepth));
    for (std::uint64_t c = next_node; c < next_node + count; ++c) depth[c] = depth[i] + 1;
    deepest = std::max<std::uint32_t>(deepest, depth[i] + 1u);
    next_node += count;
  }
  if (next_node != nodes.size()) fail("node count disagrees with the child masks");
  if (next_reference != reference_count)
    fail(std::to_string(reference_count - next_reference) + " references are in no leaf");
  return deepest;
}

}  // namespace

OctreeView::OctreeView(std::span<const format::OctreeNode> nodes,
                       std::span<const std::uint32_t> prim_ids,
                       std::span<const format::RayTriangle> triangles, const format::Box3f& bounds,
                       const std::string& name)
    : nodes_(nodes), prim_ids_(prim_ids), triangles_(triangles), bounds_(bounds) {
  auto fail = [&](const std::string& what) { throw BlobError(name + ": " + what); };
  for (int a = 0; a < 3; ++a) {
    const float lo = format::at(bounds.min, a), hi = format::at(bounds.max, a);
    if (!std::isfinite(lo) || !std::isfinite(hi) || !(lo < hi))
      fail("root cell is not a finite, non-empty box");
  }
  depth_ = check_breadth_first(nodes, prim_ids.size(), fail);
  for (std::size_t r = 0; r < prim_ids.size(); ++r)
    if (prim_ids[r] >= triangles.size())
      fail("reference " + std::to_string(r) + " names triangle " + std::to_string(prim_ids[r]) +
           " of " + std::to_string(triangles.size()));
}

OctreeView OctreeView::from_blob(const Blob& blob, const std::string& name) {
  const StructureInfo* info = blob.structure(name);
  if (info == nullptr) blob.fail("has no structure '" + name + "'");
  const auto* d = structure_table(blob, *info).desc_as<schema::OctreeDesc>();
  if (d == nullptr) blob.fail("structure '" + name + "' is a " + info->kind + ", not an octree");
  // Blob::open checked kinds, sizes and counts of these sections, and that the bounds exist.
  const auto& b = *d->bounds();
  const format::Box3f bounds{{b.min().x(), b.min().y(), b.min().z()},
                             {b.max().x(), b.max().y(), b.max().z()}};
  return OctreeView(blob.section_view<format::OctreeNode>(d->nodes()),
                    blob.section_view<std::uint32_t>(d->prim_ids()),
                    blob.section_view<format::RayTriangle>(d->triangles()), bounds,
                    blob.name() + ": " + name);
}

}  // namespace kiln
