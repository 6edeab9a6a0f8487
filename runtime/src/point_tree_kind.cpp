// The point k-d tree kind of the runtime registry ("points"): its manifest checks, view, deep
// check and description. It indexes the input's 3D points: a point set's points, or a triangle
// scene's vertices (both the blob's positions).
#include <algorithm>
#include <cstring>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "depth_first_layout.hpp"
#include "kiln/formats/point_tree.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/point_tree.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "text_format.hpp"

namespace kiln {

namespace {

constexpr std::uint32_t kSections[] = {format::kSectionPointNodes, format::kSectionPointPositions,
                                       format::kSectionPointIds};

class PointTreeStructure final : public StructureView, public NeighborQueries {
 public:
  explicit PointTreeStructure(PointTreeView view) : view_(std::move(view)) {}

  const NeighborQueries* neighbors() const override { return this; }

  std::size_t nearest(const format::Float3& query, std::span<Neighbor> out) const override {
    return view_.nearest(query, out);
  }
  void within_radius(const format::Float3& query, float radius,
                     std::vector<Neighbor>& out) const override {
    view_.within_radius(query, radius, out);
  }

 private:
  PointTreeView view_;
};

void check(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::PointTreeDesc>(blob, info);
  const auto where = "structure '" + info.name + "' ";
  // Over every input point: the ids are indices into the blob's positions.
  const std::uint64_t count = blob.input().vertex_count;
  if (d.point_count() != count)
    blob.fail_section(0, where + "holds " + std::to_string(d.point_count()) +
                             " points, the input " + std::to_string(count));
  blob.check_section(where + "nodes", d.nodes(), format::kSectionPointNodes,
                     sizeof(format::PointNode), d.node_count(), false);
  blob.check_section(where + "points", d.points(), format::kSectionPointPositions,
                     sizeof(format::Float3), count, false);
  blob.check_section(where + "point ids", d.point_ids(), format::kSectionPointIds,
                     sizeof(std::uint32_t), count, false);
  if (d.node_count() == 0) blob.fail_section(0, where + "has no nodes");
  if (d.bounds() == nullptr) blob.fail_section(0, where + "has no bounds");
}

std::unique_ptr<StructureView> open(const Blob& blob, const StructureInfo& info) {
  return std::make_unique<PointTreeStructure>(PointTreeView::from_blob(blob, info.name));
}

// Every input point exactly once, each stored point a bitwise copy of its input point.
void verify_ids(const Blob& blob, const schema::PointTreeDesc& d, const std::string& name,
                const PointTreeView& tree) {
  const auto positions = blob.positions();
  const auto ids = tree.ids();
  const auto points = tree.points();
  std::vector<bool> seen(positions.size());
  for (std::size_t i = 0; i < ids.size(); ++i) {
    if (ids[i] >= positions.size() || seen[ids[i]])
      blob.fail_section(d.point_ids(), name + " point " + std::to_string(i) + " names vertex " +
                                           std::to_string(ids[i]) + " out of range or twice");
    seen[ids[i]] = true;
    if (std::memcmp(&points[i], &positions[ids[i]], sizeof(format::Float3)) != 0)
      blob.fail_section(d.points(),
                        name + " point " + std::to_string(i) + " does not match its vertex");
  }
}

// Beyond the view's structural walk: the ids (verify_ids), and the bounds and every gap true of
// the points below them (searches prune on them).
void verify(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::PointTreeDesc>(blob, info);
  const std::string& name = info.name;
  const PointTreeView tree = PointTreeView::from_blob(blob, name);
  verify_ids(blob, d, name, tree);
  const auto points = tree.points();
  // Walk with the box every point below must lie in: the bounds, narrowed by each gap.
  walk_tree_cells<format::PointNode>(
      tree.nodes(), tree.bounds(),
      [&](std::uint32_t index, const format::PointNode& n, format::Box3f& below,
          format::Box3f& above) {
        const auto a = n.axis();
        if (!(n.below_max() <= n.above_min()))
          blob.fail_section(d.nodes(),
                            name + " node " + std::to_string(index) + " has an inverted gap");
        format::at(below.max, a) = std::min(format::at(below.max, a), n.below_max());
        format::at(above.min, a) = std::max(format::at(above.min, a), n.above_min());
      },
      [&](const format::PointNode& n, const format::Box3f& c) {
        for (std::uint32_t i = n.first_point(); i < n.first_point() + n.point_count(); ++i) {
          for (int a = 0; a < 3; ++a)
            if (!(format::at(points[i], a) >= format::at(c.min, a) &&
                  format::at(points[i], a) <= format::at(c.max, a)))
              blob.fail_section(d.nodes(), name + " point " + std::to_string(i) +
                                               " lies outside the bounds or gaps above it");
        }
      });
}

Description describe(const Blob& blob, const StructureInfo& info) {
  const auto& p = desc_of<schema::PointTreeDesc>(blob, info);
  const std::string split_rule = p.split_rule() ? p.split_rule()->str() : "";
  Description out;
  out.lines.push_back(
      printf_string("%s splits, max leaf %u", split_rule.c_str(), p.max_leaf_size()));
  out.lines.push_back(printf_string(
      "%llu points, %llu nodes, %llu leaves, depth %u, largest leaf %u, %.1f bytes/point",
      (unsigned long long)p.point_count(), (unsigned long long)p.node_count(),
      (unsigned long long)p.leaf_count(), p.max_depth(), p.largest_leaf(), p.bytes_per_point()));
  out.field("split_rule", split_rule).field("max_leaf_size", p.max_leaf_size());
  out.field("point_count", p.point_count()).field("node_count", p.node_count());
  out.field("leaf_count", p.leaf_count()).field("max_depth", p.max_depth());
  out.field("largest_leaf", p.largest_leaf()).field("bytes_per_point", p.bytes_per_point());
  return out;
}

}  // namespace

extern const StructureKind kPointTreeKind;

const StructureKind kPointTreeKind{"points",
                                   "k-d tree over 3D points: k nearest, radius",
                                   InputKind::kPoint3,
                                   kSections,
                                   std::uint8_t(schema::StructureDesc::PointTreeDesc),
                                   check,
                                   open,
                                   verify,
                                   describe};

}  // namespace kiln
