// The BVH kinds of the runtime registry: "bvh" (binned or sweep SAH builder) and "sbvh" (spatial
// splits), one BvhDesc and two layouts: binary (width 2, BvhView) and wide (width 4, 8 or 16,
// BvhWideView). Their manifest checks, view, deep check and description.
#include <cmath>
#include <cstring>
#include <memory>
#include <string>

#include "kiln/formats/bvh.hpp"
#include "kiln/formats/bvh_wide.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/bvh_wide.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "text_format.hpp"
#include "triangle_structure.hpp"

namespace kiln {

namespace {

// The layout before the arena (BVWN/BVQN, BVWT, BVHP) stays listed, so such a blob is refused
// with the message below rather than as one written by a newer tool.
constexpr std::uint32_t kSections[] = {
    format::kSectionBvhNodes,         format::kSectionBvhTriangles, format::kSectionBvhPrimIds,
    format::kSectionBvhWideArena,     format::kSectionBvhWideNodes, format::kSectionBvhPackets,
    format::kSectionBvhQuantizedNodes};

void check_wide(const Blob& blob, const schema::BvhDesc& d, const std::string& where) {
  if (d.wide_nodes() != kNoSection || d.packets() != kNoSection)
    blob.fail(where + "is a " + std::to_string(d.width()) +
              "-wide BVH in the layout before the node arena (nodes, packets and ids apart, "
              "written before 2026-11-27), which this reader no longer traces: rebuild it with "
              "kiln build and the same inputs");
  blob.check_section(where + "arena", d.wide_arena(), format::kSectionBvhWideArena,
                     format::kBvhArenaUnit, d.wide_arena_units(), false);
  if (d.wide_node_count() == 0) blob.fail_section(0, where + "has no nodes");
}

void check(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::BvhDesc>(blob, info);
  const auto where = "structure '" + info.name + "' ";
  if (d.width() == 4 || d.width() == 8 || d.width() == 16) return check_wide(blob, d, where);
  if (d.width() != 2)
    blob.fail(where + "has width " + std::to_string(d.width()) +
              " (this reader knows 2, 4, 8, 16)");
  blob.check_section(where + "nodes", d.nodes(), format::kSectionBvhNodes, sizeof(format::BvhNode),
                     d.node_count(), false);
  blob.check_section(where + "triangles", d.triangles(), format::kSectionBvhTriangles,
                     sizeof(format::RayTriangle), d.reference_count(), false);
  blob.check_section(where + "primitive ids", d.prim_ids(), format::kSectionBvhPrimIds,
                     sizeof(std::uint32_t), d.reference_count(), false);
  if (d.node_count() == 0) blob.fail_section(0, where + "has no nodes");
}

bool is_wide(const Blob& blob, const StructureInfo& info) {
  return desc_of<schema::BvhDesc>(blob, info).width() != 2;
}

std::unique_ptr<StructureView> open(const Blob& blob, const StructureInfo& info) {
  if (is_wide(blob, info))
    return std::make_unique<TriangleStructure<BvhWideView>>(
        blob, BvhWideView::from_blob(blob, info.name));
  return std::make_unique<TriangleStructure<BvhView>>(blob, BvhView::from_blob(blob, info.name));
}

bool contains(const format::BvhNode& outer, const format::BvhNode& inner) {
  for (int a = 0; a < 3; ++a)
    if (!(outer.min[a] <= inner.min[a] && inner.max[a] <= outer.max[a])) return false;
  return true;
}

// A reference names a stored triangle and carries a bitwise copy of its corners.
void check_reference(const Blob& blob, std::uint32_t section, const std::string& name,
                     const std::string& where, std::uint32_t prim,
                     const format::RayTriangle& stored) {
  const auto positions = blob.positions();
  const auto triangles = blob.triangles();
  if (prim >= triangles.size())
    blob.fail_section(section, name + " " + where + " names triangle " + std::to_string(prim));
  const auto& t = triangles[prim];
  const format::RayTriangle expected{positions[t.v[0]], positions[t.v[1]], positions[t.v[2]]};
  if (std::memcmp(&expected, &stored, sizeof(expected)) != 0)
    blob.fail_section(section, name + " " + where + " does not match its triangle's corners");
}

// Child boxes inside the box their parent slot gave them (the root's children are unchecked).
// How far a child node's boxes may reach past its parent's slot box: none for float boxes; for
// quantised ones, one quantisation step of the child plus rounding (each plane is rounded
// outwards to the child's own grid, not clipped to the parent's).
template <int W>
float slack(const format::BvhWideNode<W>&, int, float) {
  return 0.0f;
}
template <int W>
float slack(const format::BvhQuantizedNode<W>& n, int axis, float at) {
  return format::bvh_quantized_scale(n.exponent[axis]) + std::fabs(at) * 0x1p-21f;
}

template <class Node>
void verify_wide_nodes(const Blob& blob, const schema::BvhDesc& d, const std::string& name,
                       const BvhWideView& bvh) {
  constexpr int W = int(sizeof(Node::child) / sizeof(Node::child[0]));
  std::size_t index = 0;
  bvh.for_each_node<Node>([&](const Node& n) {
    for (int k = 0; k < W; ++k) {
      if (n.child[k] & format::kBvhLeafFlag) {
        for (const auto& p : bvh.leaf(n.child[k], n.packets[k]))
          for (std::uint32_t lane = 0; lane < format::kBvhPacketSize; ++lane) {
            const format::RayTriangle stored{{p.v[0][0][lane], p.v[0][1][lane], p.v[0][2][lane]},
                                             {p.v[1][0][lane], p.v[1][1][lane], p.v[1][2][lane]},
                                             {p.v[2][0][lane], p.v[2][1][lane], p.v[2][2][lane]}};
            check_reference(blob, d.wide_arena(), name, "node " + std::to_string(index),
                            p.prim[lane], stored);
          }
        continue;
      }
      float lo[3], hi[3];
      format::bvh_child_box(n, k, lo, hi);
      const Node& c = bvh.node<Node>(n.child[k]);
      for (int j = 0; j < W; ++j) {
        if (c.child[j] == format::kBvhLeafFlag && c.packets[j] == 0) continue;  // empty slot
        float clo[3], chi[3];
        format::bvh_child_box(c, j, clo, chi);
        for (int a = 0; a < 3; ++a)
          if (!(lo[a] - slack(c, a, lo[a]) <= clo[a] && chi[a] <= hi[a] + slack(c, a, hi[a])))
            blob.fail_section(d.wide_arena(), name + " node " + std::to_string(index) +
                                                  " does not contain its children");
      }
    }
    index += 1;
  });
}

void verify_wide(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::BvhDesc>(blob, info);
  const BvhWideView bvh = BvhWideView::from_blob(blob, info.name, BvhKernel::kScalar);
  if (bvh.width() == 16)
    verify_wide_nodes<format::BvhNode16>(blob, d, info.name, bvh);
  else if (bvh.quantized())
    bvh.width() == 4 ? verify_wide_nodes<format::BvhQNode4>(blob, d, info.name, bvh)
                     : verify_wide_nodes<format::BvhQNode8>(blob, d, info.name, bvh);
  else
    bvh.width() == 4 ? verify_wide_nodes<format::BvhNode4>(blob, d, info.name, bvh)
                     : verify_wide_nodes<format::BvhNode8>(blob, d, info.name, bvh);
}

// Beyond the view's structural walk: every box inside its parent's, every reference naming a
// stored triangle and carrying a bitwise copy of its corners.
void verify(const Blob& blob, const StructureInfo& info) {
  if (is_wide(blob, info)) return verify_wide(blob, info);
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
  const std::string presplit = b.presplit() ? b.presplit()->str() : std::string("none");
  if (presplit != "none")
    parameters += printf_string(
        ", presplit %s (threshold %g x scene volume, at most %u per "
        "triangle: %llu build references)",
        presplit.c_str(), b.evh_threshold(), b.evh_max_refs(),
        (unsigned long long)b.presplit_references());
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
  out.field("bytes_per_triangle", b.bytes_per_triangle()).field("width", b.width());
  out.field("presplit", presplit);
  if (presplit != "none")
    out.field("evh_threshold", b.evh_threshold())
        .field("evh_max_refs", b.evh_max_refs())
        .field("presplit_references", b.presplit_references());
  if (b.width() == 2) return out;
  out.lines.push_back(printf_string(
      "%u-wide layout, %s child boxes: %llu nodes, %llu leaves, depth %u, %llu packets of 4, "
      "%.1f%% packet fill",
      b.width(), b.quantized() ? "8-bit" : "float", (unsigned long long)b.wide_node_count(),
      (unsigned long long)b.wide_leaf_count(), b.wide_max_depth(),
      (unsigned long long)b.packet_count(), 100.0 * b.packet_fill()));
  out.field("wide_node_count", b.wide_node_count()).field("wide_leaf_count", b.wide_leaf_count());
  out.field("packet_count", b.packet_count()).field("wide_max_depth", b.wide_max_depth());
  out.field("packet_fill", b.packet_fill()).field("quantized", b.quantized());
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
