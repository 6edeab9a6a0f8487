// The octree kind of the runtime registry ("octree"): its manifest checks, view, deep check and
// description.
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "kiln/formats/octree.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/octree.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "kiln/runtime/triangle_geometry.hpp"
#include "text_format.hpp"
#include "triangle_structure.hpp"

namespace kiln {

namespace {

constexpr std::uint32_t kSections[] = {format::kSectionOctreeNodes, format::kSectionOctreePrimIds,
                                       format::kSectionOctreeTriangles};

void check(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::OctreeDesc>(blob, info);
  const auto where = "structure '" + info.name + "' ";
  blob.check_section(where + "nodes", d.nodes(), format::kSectionOctreeNodes,
                     sizeof(format::OctreeNode), d.node_count(), false);
  blob.check_section(where + "primitive ids", d.prim_ids(), format::kSectionOctreePrimIds,
                     sizeof(std::uint32_t), d.reference_count(), false);
  blob.check_section(where + "triangles", d.triangles(), format::kSectionOctreeTriangles,
                     sizeof(format::RayTriangle), blob.input().triangle_count, false);
  if (d.node_count() == 0) blob.fail_section(0, where + "has no nodes");
  if (d.bounds() == nullptr) blob.fail_section(0, where + "has no bounds");
}

std::unique_ptr<StructureView> open(const Blob& blob, const StructureInfo& info) {
  return std::make_unique<TriangleStructure<OctreeView>>(blob,
                                                         OctreeView::from_blob(blob, info.name));
}

// Beyond the view's structural walk: the triangle copies equal to the input's, every triangle in
// at least one leaf, and every leaf's triangles overlapping its cell (exact separating-axis test).
void verify(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::OctreeDesc>(blob, info);
  const std::string& name = info.name;
  const OctreeView tree = OctreeView::from_blob(blob, name);
  verify_triangle_copies(blob, d.triangles(), name, tree.triangles());
  verify_every_triangle_listed(blob, d.prim_ids(), name, tree.prim_ids());
  const auto prim_ids = tree.prim_ids();
  const auto copies = tree.triangles();
  for_each_octree_leaf(tree, [&](const format::OctreeNode& n, const format::Box3f& cell) {
    for (std::uint32_t i = n.first_reference(), end = i + n.reference_count(); i < end; ++i) {
      const format::RayTriangle& t = copies[prim_ids[i]];
      if (!triangle_overlaps_box(to_d(t.v0), to_d(t.v1), to_d(t.v2), to_d(cell.min),
                                 to_d(cell.max)))
        blob.fail_section(d.prim_ids(), name + " triangle " + std::to_string(prim_ids[i]) +
                                            " lies outside the cell of its leaf");
    }
  });
}

Description describe(const Blob& blob, const StructureInfo& info) {
  const auto& k = desc_of<schema::OctreeDesc>(blob, info);
  Description out;
  out.lines.push_back(printf_string("leaf size %u, depth limit %u, reference budget %u%s",
                                    k.leaf_size(), k.depth_limit(), k.reference_budget(),
                                    k.budget_reached() ? " (reached)" : ""));
  out.lines.push_back(
      printf_string("%llu nodes, %llu leaves, %llu empty cells, depth %u, largest leaf %u",
                    (unsigned long long)k.node_count(), (unsigned long long)k.leaf_count(),
                    (unsigned long long)k.empty_cell_count(), k.max_depth(), k.largest_leaf()));
  out.lines.push_back(printf_string(
      "%llu references (%.3f per triangle), %.1f bytes/triangle; over leaf size: %llu at the depth "
      "limit, %llu without progress",
      (unsigned long long)k.reference_count(), k.references_per_triangle(), k.bytes_per_triangle(),
      (unsigned long long)k.depth_limited_leaves(), (unsigned long long)k.stalled_leaves()));
  out.field("leaf_size", k.leaf_size()).field("depth_limit", k.depth_limit());
  out.field("reference_budget", k.reference_budget()).field("budget_reached", k.budget_reached());
  out.field("node_count", k.node_count()).field("leaf_count", k.leaf_count());
  out.field("empty_cell_count", k.empty_cell_count());
  out.field("reference_count", k.reference_count()).field("max_depth", k.max_depth());
  out.field("largest_leaf", k.largest_leaf());
  out.field("depth_limited_leaves", k.depth_limited_leaves());
  out.field("stalled_leaves", k.stalled_leaves());
  out.field("references_per_triangle", k.references_per_triangle());
  out.field("bytes_per_triangle", k.bytes_per_triangle());
  return out;
}

}  // namespace

extern const StructureKind kOctreeKind;

const StructureKind kOctreeKind{"octree",
                                "octree over triangles: rays, closest point, inside, box",
                                InputKind::kTriangles,
                                kSections,
                                std::uint8_t(schema::StructureDesc::OctreeDesc),
                                check,
                                open,
                                verify,
                                describe};

}  // namespace kiln
