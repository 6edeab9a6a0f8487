// The BVH kinds of the runtime registry: "bvh" (binned or sweep SAH builder) and "sbvh" (spatial
// splits), one layout and one BvhDesc. Their manifest checks, view, deep check and description.
#include <cstring>
#include <memory>
#include <string>

#include "kiln/formats/bvh.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "text_format.hpp"
#include "triangle_structure.hpp"

namespace kiln {

namespace {

constexpr std::uint32_t kSections[] = {format::kSectionBvhNodes, format::kSectionBvhTriangles,
                                       format::kSectionBvhPrimIds};

void check(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::BvhDesc>(blob, info);
  const auto where = "structure '" + info.name + "' ";
  blob.check_section(where + "nodes", d.nodes(), format::kSectionBvhNodes, sizeof(format::BvhNode),
                     d.node_count(), false);
  blob.check_section(where + "triangles", d.triangles(), format::kSectionBvhTriangles,
                     sizeof(format::RayTriangle), d.reference_count(), false);
  blob.check_section(where + "primitive ids", d.prim_ids(), format::kSectionBvhPrimIds,
                     sizeof(std::uint32_t), d.reference_count(), false);
  if (d.node_count() == 0) blob.fail_section(0, where + "has no nodes");
}

std::unique_ptr<StructureView> open(const Blob& blob, const StructureInfo& info) {
  return std::make_unique<TriangleStructure<BvhView>>(blob, BvhView::from_blob(blob, info.name));
}

bool contains(const format::BvhNode& outer, const format::BvhNode& inner) {
  for (int a = 0; a < 3; ++a)
    if (!(outer.min[a] <= inner.min[a] && inner.max[a] <= outer.max[a])) return false;
  return true;
}

// Beyond the view's structural walk: every box inside its parent's, every reference naming a
// stored triangle and carrying a bitwise copy of its corners.
void verify(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::BvhDesc>(blob, info);
  const std::string& name = info.name;
  const BvhView bvh = BvhView::from_blob(blob, name);
  const auto nodes = bvh.nodes();
  for (std::uint32_t i = 0; i < nodes.size(); ++i) {
    const auto& n = nodes[i];
    if (n.count > 0) continue;
    if (!contains(n, nodes[i + 1]) || !contains(n, nodes[n.offset]))
      blob.fail_section(d.nodes(),
                        name + " node " + std::to_string(i) + " does not contain its children");
  }
  const auto positions = blob.positions();
  const auto triangles = blob.triangles();
  const auto prim_ids = bvh.prim_ids();
  const auto leaf_triangles = bvh.triangles();
  for (std::size_t r = 0; r < prim_ids.size(); ++r) {
    if (prim_ids[r] >= triangles.size())
      blob.fail_section(d.prim_ids(), name + " reference " + std::to_string(r) +
                                          " names triangle " + std::to_string(prim_ids[r]));
    const auto& t = triangles[prim_ids[r]];
    const format::RayTriangle expected{positions[t.v[0]], positions[t.v[1]], positions[t.v[2]]};
    if (std::memcmp(&expected, &leaf_triangles[r], sizeof(expected)) != 0)
      blob.fail_section(d.triangles(), name + " reference " + std::to_string(r) +
                                           " does not match its triangle's corners");
  }
}

Description describe(const Blob& blob, const StructureInfo& info) {
  const auto& b = desc_of<schema::BvhDesc>(blob, info);
  const std::string builder = b.builder() ? b.builder()->str() : std::string();
  Description out;
  std::string parameters = printf_string(
      "builder %s, %u bins, max leaf %u, SAH constants Ct %g Ci %g", builder.c_str(), b.bins(),
      b.max_leaf_size(), double(b.traversal_cost()), double(b.intersection_cost()));
  if (builder == "sbvh")
    parameters += printf_string(", alpha %g, max duplication %g", double(b.sbvh_alpha()),
                                double(b.sbvh_max_duplication()));
  out.lines.push_back(parameters);
  out.lines.push_back(printf_string("%llu nodes, %llu leaves, depth %u, leaf size avg %.2f max %u",
                                    (unsigned long long)b.node_count(),
                                    (unsigned long long)b.leaf_count(), b.max_depth(),
                                    b.average_leaf_size(), b.largest_leaf()));
  out.lines.push_back(
      printf_string("%llu references (%.3f per triangle), SAH cost %.3f, %.1f bytes/triangle",
                    (unsigned long long)b.reference_count(), b.duplication_factor(), b.sah_cost(),
                    b.bytes_per_triangle()));
  out.field("builder", builder).field("bins", b.bins());
  out.field("traversal_cost", b.traversal_cost()).field("intersection_cost", b.intersection_cost());
  out.field("max_leaf_size", b.max_leaf_size()).field("sbvh_alpha", b.sbvh_alpha());
  out.field("sbvh_max_duplication", b.sbvh_max_duplication());
  out.field("node_count", b.node_count()).field("leaf_count", b.leaf_count());
  out.field("reference_count", b.reference_count()).field("max_depth", b.max_depth());
  out.field("largest_leaf", b.largest_leaf()).field("average_leaf_size", b.average_leaf_size());
  out.field("duplication_factor", b.duplication_factor()).field("sah_cost", b.sah_cost());
  out.field("bytes_per_triangle", b.bytes_per_triangle());
  return out;
}

}  // namespace

extern const StructureKind kBvhKind, kSbvhKind;

const StructureKind kBvhKind{"bvh",
                             "BVH (binned or sweep SAH): rays, closest point, inside, box",
                             InputKind::kTriangles,
                             kSections,
                             std::uint8_t(schema::StructureDesc::BvhDesc),
                             check,
                             open,
                             verify,
                             describe};

const StructureKind kSbvhKind{"sbvh",
                              "BVH with spatial splits: rays, closest point, inside, box",
                              InputKind::kTriangles,
                              kSections,
                              std::uint8_t(schema::StructureDesc::BvhDesc),
                              check,
                              open,
                              verify,
                              describe};

}  // namespace kiln
