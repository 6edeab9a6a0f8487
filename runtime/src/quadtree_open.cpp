// Opens a quadtree view from a blob: its sections, its root cell and the point table it indexes.
#include <string>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/quadtree.hpp"

namespace kiln {

QuadtreeView QuadtreeView::from_blob(const Blob& blob, const std::string& name) {
  const StructureInfo* info = blob.structure(name);
  const auto* d = info ? structure_table(blob, *info).desc_as<schema::QuadtreeDesc>() : nullptr;
  if (d == nullptr) blob.fail("has no quadtree '" + name + "'");
  // Blob::open checked kinds, sizes and counts of these sections, and the root's presence.
  const auto* r = d->root();
  const format::Box2d root{{r->min().x(), r->min().y()}, {r->max().x(), r->max().y()}};
  return QuadtreeView(blob.section_view<format::QuadNode>(d->nodes()),
                      blob.section_view<format::Double2>(d->points()),
                      blob.section_view<std::uint32_t>(d->point_ids()), root,
                      blob.point_table().points.size(), blob.name() + ": " + name);
}

}  // namespace kiln
