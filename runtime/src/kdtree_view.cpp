// The k-d tree view's structural check, and its view of a blob's structure.
#include <string>
#include <vector>

#include "depth_first_layout.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/kdtree.hpp"
#include "kiln/runtime/manifest.hpp"

namespace kiln {

KdTreeView::KdTreeView(std::span<const format::KdNode> nodes,
                       std::span<const std::uint32_t> prim_ids,
                       std::span<const format::RayTriangle> triangles, const format::Box3f& bounds,
                       const std::string& name)
    : nodes_(nodes), prim_ids_(prim_ids), triangles_(triangles), bounds_(bounds) {
  auto fail = [&](const std::string& what) { throw BlobError(name + ": " + what); };
  check_depth_first_layout<format::KdNode>(
      nodes, format::kKdMaxDepth, prim_ids.size(), "references",
      [](const format::KdNode& n) {
        return std::pair<std::uint64_t, std::uint64_t>{n.first_reference(), n.reference_count()};
      },
      fail);
  for (std::size_t r = 0; r < prim_ids.size(); ++r)
    if (prim_ids[r] >= triangles.size())
      fail("reference " + std::to_string(r) + " names triangle " + std::to_string(prim_ids[r]) +
           " of " + std::to_string(triangles.size()));
}

KdTreeView KdTreeView::from_blob(const Blob& blob, const std::string& name) {
  const StructureInfo* info = blob.structure(name);
  if (info == nullptr) blob.fail("has no structure '" + name + "'");
  const auto* d = structure_table(blob, *info).desc_as<schema::KdTreeDesc>();
  if (d == nullptr) blob.fail("structure '" + name + "' is a " + info->kind + ", not a k-d tree");
  // Blob::open checked kinds, sizes and counts of these sections, and that the bounds exist.
  const auto& b = *d->bounds();
  const format::Box3f bounds{{b.min().x(), b.min().y(), b.min().z()},
                             {b.max().x(), b.max().y(), b.max().z()}};
  return KdTreeView(blob.section_view<format::KdNode>(d->nodes()),
                    blob.section_view<std::uint32_t>(d->prim_ids()),
                    blob.section_view<format::RayTriangle>(d->triangles()), bounds,
                    blob.name() + ": " + name);
}

}  // namespace kiln
