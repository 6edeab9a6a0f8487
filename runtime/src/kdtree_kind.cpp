// The SAH k-d tree kind of the runtime registry ("kdtree"): its manifest checks, view, deep check
// and description.
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "depth_first_layout.hpp"
#include "kiln/formats/kdtree.hpp"
#include "kiln/runtime/kdtree.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "text_format.hpp"
#include "triangle_structure.hpp"

namespace kiln {

namespace {

constexpr std::uint32_t kSections[] = {format::kSectionKdNodes, format::kSectionKdPrimIds,
                                       format::kSectionKdTriangles};

void check(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::KdTreeDesc>(blob, info);
  const auto where = "structure '" + info.name + "' ";
  blob.check_section(where + "nodes", d.nodes(), format::kSectionKdNodes, sizeof(format::KdNode),
                     d.node_count(), false);
  blob.check_section(where + "primitive ids", d.prim_ids(), format::kSectionKdPrimIds,
                     sizeof(std::uint32_t), d.reference_count(), false);
  blob.check_section(where + "triangles", d.triangles(), format::kSectionKdTriangles,
                     sizeof(format::RayTriangle), blob.input().triangle_count, false);
  if (d.node_count() == 0) blob.fail_section(0, where + "has no nodes");
  if (d.bounds() == nullptr) blob.fail_section(0, where + "has no bounds");
}

std::unique_ptr<StructureView> open(const Blob& blob, const StructureInfo& info) {
  return std::make_unique<TriangleStructure<KdTreeView>>(blob,
                                                         KdTreeView::from_blob(blob, info.name));
}

// Beyond the view's structural walk: the triangle copies equal to the input's, every triangle in
// at least one leaf, and splits inside their cells.
void verify(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::KdTreeDesc>(blob, info);
  const std::string& name = info.name;
  const KdTreeView tree = KdTreeView::from_blob(blob, name);
  verify_triangle_copies(blob, d.triangles(), name, tree.triangles());
  verify_every_triangle_listed(blob, d.prim_ids(), name, tree.prim_ids());
  walk_tree_cells<format::KdNode>(
      tree.nodes(), tree.bounds(),
      [&](std::uint32_t index, const format::KdNode& n, format::Box3f& below,
          format::Box3f& above) {
        const auto a = n.axis();
        if (!(n.split() > format::at(below.min, a) && n.split() < format::at(below.max, a)))
          blob.fail_section(d.nodes(),
                            name + " node " + std::to_string(index) + " splits outside its cell");
        format::at(below.max, a) = format::at(above.min, a) = n.split();
      },
      [](const format::KdNode&, const format::Box3f&) {});
}

Description describe(const Blob& blob, const StructureInfo& info) {
  const auto& k = desc_of<schema::KdTreeDesc>(blob, info);
  Description out;
  out.lines.push_back(printf_string("SAH constants Ct %g Ci %g, empty bonus %g, depth limit %u",
                                    double(k.traversal_cost()), double(k.intersection_cost()),
                                    double(k.empty_bonus()), k.depth_limit()));
  out.lines.push_back(
      printf_string("%llu nodes, %llu leaves (%llu empty), depth %u, largest leaf %u",
                    (unsigned long long)k.node_count(), (unsigned long long)k.leaf_count(),
                    (unsigned long long)k.empty_leaf_count(), k.max_depth(), k.largest_leaf()));
  out.lines.push_back(
      printf_string("%llu references (%.3f per triangle), SAH cost %.3f, %.1f bytes/triangle",
                    (unsigned long long)k.reference_count(), k.references_per_triangle(),
                    k.sah_cost(), k.bytes_per_triangle()));
  out.field("traversal_cost", k.traversal_cost()).field("intersection_cost", k.intersection_cost());
  out.field("empty_bonus", k.empty_bonus()).field("depth_limit", k.depth_limit());
  out.field("node_count", k.node_count()).field("leaf_count", k.leaf_count());
  out.field("empty_leaf_count", k.empty_leaf_count());
  out.field("reference_count", k.reference_count()).field("max_depth", k.max_depth());
  out.field("largest_leaf", k.largest_leaf());
  out.field("references_per_triangle", k.references_per_triangle());
  out.field("sah_cost", k.sah_cost()).field("bytes_per_triangle", k.bytes_per_triangle());
  return out;
}

}  // namespace

extern const StructureKind kKdTreeKind;

const StructureKind kKdTreeKind{"kdtree",
                                "SAH k-d tree: rays, closest point, inside, box",
                                InputKind::kTriangles,
                                kSections,
                                std::uint8_t(schema::StructureDesc::KdTreeDesc),
                                check,
                                open,
                                verify,
                                describe};

}  // namespace kiln
