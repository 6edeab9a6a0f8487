#include <string>
#include <vector>

#include "depth_first_layout.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/point_tree.hpp"

namespace kiln {

PointTreeView::PointTreeView(std::span<const format::PointNode> nodes,
                             std::span<const format::Float3> points,
                             std::span<const std::uint32_t> ids, const format::Box3f& bounds,
                             const std::string& name)
    : nodes_(nodes), points_(points), ids_(ids), bounds_(bounds) {
  auto fail = [&](const std::string& what) { throw BlobError(name + ": " + what); };
  if (points.size() != ids.size())
    fail(std::to_string(points.size()) + " points but " + std::to_string(ids.size()) + " ids");
  check_depth_first_layout<format::PointNode>(
      nodes, format::kPointMaxDepth, points.size(), "points",
      [](const format::PointNode& n) {
        return std::pair<std::uint64_t, std::uint64_t>{n.first_point(), n.point_count()};
      },
      fail);
}

PointTreeView PointTreeView::from_blob(const Blob& blob, const std::string& name) {
  const StructureInfo* info = blob.structure(name);
  const auto* d = info ? structure_table(blob, *info).desc_as<schema::PointTreeDesc>() : nullptr;
  if (d == nullptr) blob.fail("has no point k-d tree '" + name + "'");
  // Blob::open checked kinds, sizes and counts of these sections, and the bounds' presence.
  const auto* b = d->bounds();
  const format::Box3f bounds{{b->min().x(), b->min().y(), b->min().z()},
                             {b->max().x(), b->max().y(), b->max().z()}};
  return PointTreeView(blob.section_view<format::PointNode>(d->nodes()),
                       blob.section_view<format::Float3>(d->points()),
                       blob.section_view<std::uint32_t>(d->point_ids()), bounds,
                       blob.name() + ": " + name);
}

}  // namespace kiln
