// The quadtree kind of the runtime registry ("quadtree"): its manifest checks, view, deep check
// and description. It indexes the blob's 2D point table.
#include <algorithm>
#include <cstring>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "kiln/formats/quadtree.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/quadtree.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "text_format.hpp"

namespace kiln {

namespace {

constexpr std::uint32_t kSections[] = {format::kSectionQuadNodes, format::kSectionQuadPoints,
                                       format::kSectionQuadIds};

class QuadtreeStructure final : public StructureView, public Point2Queries {
 public:
  explicit QuadtreeStructure(QuadtreeView view) : view_(std::move(view)) {}

  const Point2Queries* points2() const override { return this; }

  void range(const format::Box2d& box, std::vector<std::uint32_t>& out) const override {
    view_.range(box, out);
  }
  void range_counting(const format::Box2d& box, std::vector<std::uint32_t>& out,
                      Cost& cost) const override {
    view_.range_counting(box, out, cost);
  }
  std::size_t nearest(const format::Double2& q, std::span<Neighbor2> out) const override {
    return view_.nearest(q, out);
  }
  void within_radius(const format::Double2& q, double radius,
                     std::vector<Neighbor2>& out) const override {
    view_.within_radius(q, radius, out);
  }
  void cells(std::vector<IndexCell2>& out) const override { view_.cells(out); }

 private:
  QuadtreeView view_;
};

void check(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::QuadtreeDesc>(blob, info);
  const auto where = "structure '" + info.name + "' ";
  // Over every point of the table: the ids are indices into its points.
  const std::uint64_t count = blob.point_table().points.size();
  if (d.point_count() != count)
    blob.fail_section(0, where + "holds " + std::to_string(d.point_count()) +
                             " points, the table " + std::to_string(count));
  blob.check_section(where + "nodes", d.nodes(), format::kSectionQuadNodes,
                     sizeof(format::QuadNode), d.node_count(), false);
  blob.check_section(where + "points", d.points(), format::kSectionQuadPoints,
                     sizeof(format::Double2), count, false);
  blob.check_section(where + "point ids", d.point_ids(), format::kSectionQuadIds,
                     sizeof(std::uint32_t), count, false);
  if (d.node_count() == 0) blob.fail_section(0, where + "has no nodes");
  if (d.root() == nullptr || d.bounds() == nullptr)
    blob.fail_section(0, where + "has no root cell or bounds");
}

std::unique_ptr<StructureView> open(const Blob& blob, const StructureInfo& info) {
  return std::make_unique<QuadtreeStructure>(QuadtreeView::from_blob(blob, info.name));
}

// Every table point exactly once, each stored point a bitwise copy of its table point.
void verify_ids(const Blob& blob, const schema::QuadtreeDesc& d, const std::string& name,
                const QuadtreeView& tree) {
  const auto table = blob.point_table().points;
  const auto ids = tree.ids();
  const auto points = tree.points();
  std::vector<bool> seen(table.size());
  for (std::size_t i = 0; i < ids.size(); ++i) {
    if (seen[ids[i]])  // the view checked ids[i] < table.size()
      blob.fail_section(d.point_ids(),
                        name + " names table point " + std::to_string(ids[i]) + " twice");
    seen[ids[i]] = true;
    if (std::memcmp(&points[i], &table[ids[i]], sizeof(format::Double2)) != 0)
      blob.fail_section(d.points(),
                        name + " point " + std::to_string(i) + " does not match its table point");
  }
}

// Beyond the view's structural walk: the ids (verify_ids), and every point in the quadrant of
// each cell above it, as the builder cut them (queries prune and report whole cells on that).
void verify(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::QuadtreeDesc>(blob, info);
  const std::string& name = info.name;
  const QuadtreeView tree = QuadtreeView::from_blob(blob, name);
  verify_ids(blob, d, name, tree);
  const auto nodes = tree.nodes();
  const auto points = tree.points();
  for (const auto& p : points)
    if (!tree.root().contains(p))
      blob.fail_section(d.nodes(), name + " has a point outside its root cell");
  struct Pending {
    std::uint32_t node;
    format::Box2d cell;
  };
  std::vector<Pending> stack{{0, tree.root()}};
  while (!stack.empty()) {
    const Pending p = stack.back();
    stack.pop_back();
    const format::QuadNode& n = nodes[p.node];
    for (std::uint32_t c = p.node + 1; !n.is_leaf() && c < n.end(); c = nodes[c].end()) {
      const format::QuadNode& child = nodes[c];
      for (std::uint32_t i = child.first; i < child.first + child.count; ++i)
        if (format::quad_quadrant(p.cell, points[i]) != child.quadrant())
          blob.fail_section(d.nodes(), name + " point " + std::to_string(i) +
                                           " lies outside the quadrant of node " +
                                           std::to_string(c));
      stack.push_back({c, format::quad_child_cell(p.cell, child.quadrant())});
    }
  }
}

// Nodes, leaves and bucketed points per level, and leaves per bucket size.
void describe_levels(const QuadtreeView& tree, Description& out) {
  std::vector<std::array<std::uint64_t, 3>> levels;
  std::map<std::uint32_t, std::uint64_t> buckets;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> stack{{0, 0}};
  const auto nodes = tree.nodes();
  while (!stack.empty()) {
    const auto [node, level] = stack.back();
    stack.pop_back();
    if (levels.size() <= level) levels.resize(level + 1, {0, 0, 0});
    const format::QuadNode& n = nodes[node];
    levels[level][0] += 1;
    if (n.is_leaf()) {
      levels[level][1] += 1, levels[level][2] += n.count, buckets[n.count] += 1;
      continue;
    }
    for (std::uint32_t c = node + 1; c < n.end(); c = nodes[c].end())
      stack.push_back({c, level + 1});
  }
  DescTable per_level{"levels", {"level", "nodes", "leaves", "points"}, {}};
  std::string line = "per level (nodes/leaves/points):";
  for (std::size_t l = 0; l < levels.size(); ++l) {
    per_level.rows.push_back({std::uint64_t(l), levels[l][0], levels[l][1], levels[l][2]});
    line += printf_string(" %zu:%llu/%llu/%llu", l, (unsigned long long)levels[l][0],
                          (unsigned long long)levels[l][1], (unsigned long long)levels[l][2]);
  }
  DescTable per_bucket{"buckets", {"points", "leaves"}, {}};
  std::string bucket_line = "leaves by bucket size:";
  for (const auto& [size, leaves] : buckets) {
    per_bucket.rows.push_back({std::uint64_t(size), leaves});
    bucket_line += printf_string(" %u:%llu", size, (unsigned long long)leaves);
  }
  out.lines.push_back(line);
  out.lines.push_back(bucket_line);
  out.tables.push_back(std::move(per_level));
  out.tables.push_back(std::move(per_bucket));
}

Description describe(const Blob& blob, const StructureInfo& info) {
  const auto& q = desc_of<schema::QuadtreeDesc>(blob, info);
  Description out;
  out.lines.push_back(
      printf_string("bucket size %u, max depth %u", q.bucket_size(), q.max_depth()));
  out.lines.push_back(printf_string(
      "%llu points, %llu nodes, %llu leaves, depth %u, largest bucket %u, %.1f bytes/point",
      (unsigned long long)q.point_count(), (unsigned long long)q.node_count(),
      (unsigned long long)q.leaf_count(), q.depth(), q.largest_bucket(), q.bytes_per_point()));
  out.field("bucket_size", q.bucket_size()).field("max_depth", q.max_depth());
  out.field("point_count", q.point_count()).field("node_count", q.node_count());
  out.field("leaf_count", q.leaf_count()).field("depth", q.depth());
  out.field("largest_bucket", q.largest_bucket()).field("bytes_per_point", q.bytes_per_point());
  describe_levels(QuadtreeView::from_blob(blob, info.name), out);
  return out;
}

}  // namespace

extern const StructureKind kQuadtreeKind;

const StructureKind kQuadtreeKind{"quadtree",
                                  "bucket PR quadtree over 2D points: range, k nearest, radius",
                                  InputKind::kPoint2,
                                  kSections,
                                  std::uint8_t(schema::StructureDesc::QuadtreeDesc),
                                  check,
                                  open,
                                  verify,
                                  describe};

}  // namespace kiln
