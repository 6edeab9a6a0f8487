// The deep check behind `kiln verify`: everything open() skipped because it is O(bytes).
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/checksum.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/esvo.hpp"
#include "kiln/runtime/kdtree.hpp"
#include "kiln/runtime/point_tree.hpp"
#include "kiln/runtime/voxel_dag.hpp"

namespace kiln {

namespace {

struct Cell {
  float lo[3], hi[3];
};

// Depth-first walk of a validated two-way tree (below child next, `above_child()` beside),
// handing each node the cell it owns: the root's box, cut on the way down by `split(index, node,
// below, above)`, which receives two copies of the parent's cell to narrow.
template <class Node, class Split, class Leaf>
void walk_cells(std::span<const Node> nodes, const float lo[3], const float hi[3], Split split,
                Leaf leaf) {
  struct Pending {
    std::uint32_t node;
    Cell cell;
  };
  std::vector<Pending> stack(1);
  for (int a = 0; a < 3; ++a) stack[0].cell.lo[a] = lo[a], stack[0].cell.hi[a] = hi[a];
  while (!stack.empty()) {
    const Pending p = stack.back();
    stack.pop_back();
    const Node& n = nodes[p.node];
    if (n.is_leaf()) {
      leaf(n, p.cell);
      continue;
    }
    Pending below{p.node + 1, p.cell}, above{n.above_child(), p.cell};
    split(p.node, n, below.cell, above.cell);
    stack.push_back(above);
    stack.push_back(below);
  }
}

}  // namespace

void Blob::verify() const {
  std::uint64_t previous_end =
      header_.section_table_offset + sections_.size() * sizeof(format::SectionEntry);
  for (std::uint32_t i = 0; i < sections_.size(); ++i) {
    const auto& s = sections_[i];
    for (std::uint64_t p = previous_end; p < s.offset; ++p)
      if (bytes_[p] != std::byte{0})
        fail("padding byte at offset " + std::to_string(p) + " before section " +
             std::to_string(i) + " is not zero");
    previous_end = s.offset + s.stored_size;
    if (xxh3_64(bytes_.subspan(s.offset, s.stored_size)) != s.checksum)
      fail_section(i, "checksum mismatch (payload is corrupt)");
  }

  const auto scene_positions = positions();
  for (std::size_t v = 0; v < scene_positions.size(); ++v) {
    const auto& p = scene_positions[v];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      fail_section(manifest_->geometry()->positions(),
                   "vertex " + std::to_string(v) + " is not finite");
  }
  const auto vertex_count = scene_positions.size();
  const auto scene_triangles = triangles();
  for (std::size_t t = 0; t < scene_triangles.size(); ++t)
    for (const std::uint32_t v : scene_triangles[t].v)
      if (v >= vertex_count)
        fail_section(manifest_->geometry()->triangles(), "triangle " + std::to_string(t) +
                                                             " names vertex " + std::to_string(v) +
                                                             " of " + std::to_string(vertex_count));

  // Each mesh owns its triangle range, and its triangles index only its own vertices.
  const auto mesh_ids = triangle_mesh_ids();
  const auto* meshes = manifest_->meshes();
  const std::uint32_t mesh_count = meshes ? meshes->size() : 0;
  for (std::size_t t = 0; t < mesh_ids.size(); ++t) {
    const std::uint32_t id = mesh_ids[t];
    const auto where = "triangle " + std::to_string(t);
    if (id >= mesh_count)
      fail_section(
          manifest_->geometry()->triangle_mesh(),
          where + " names mesh " + std::to_string(id) + " of " + std::to_string(mesh_count));
    const auto* mesh = meshes->Get(id);
    if (t < mesh->first_triangle() || t - mesh->first_triangle() >= mesh->triangle_count())
      fail_section(manifest_->geometry()->triangle_mesh(),
                   where + " lies outside the range of its mesh " + std::to_string(id));
    for (const std::uint32_t v : scene_triangles[t].v)
      if (v < mesh->first_vertex() || v - mesh->first_vertex() >= mesh->vertex_count())
        fail_section(manifest_->geometry()->triangles(),
                     where + " names vertex " + std::to_string(v) + " outside its mesh");
  }
  verify_accelerations();
}

void Blob::verify_accelerations() const {
  const auto* accels = manifest_->accelerations();
  if (accels == nullptr) return;
  for (const auto* accel : *accels) {
    if (accel->bvh() != nullptr) verify_bvh(*accel);
    if (accel->kdtree() != nullptr) verify_kdtree(*accel);
    if (accel->points() != nullptr) verify_point_tree(*accel);
    if (accel->dag() != nullptr) verify_voxel_dag(*accel);
    if (accel->esvo() != nullptr) verify_esvo(*accel);
  }
}

void Blob::verify_bvh(const schema::Acceleration& accel_table) const {
  const auto* accel = &accel_table;
  const auto positions_view = positions();
  const auto triangles_view = triangles();
  {
    const std::string name = accel->kind()->str();
    const BvhView bvh = BvhView::from_blob(*this, name);  // structure: order, ranges, depth
    const auto nodes = bvh.nodes();
    auto contains = [](const format::BvhNode& outer, const format::BvhNode& inner) {
      for (int a = 0; a < 3; ++a)
        if (!(outer.min[a] <= inner.min[a] && inner.max[a] <= outer.max[a])) return false;
      return true;
    };
    for (std::uint32_t i = 0; i < nodes.size(); ++i) {
      const auto& n = nodes[i];
      if (n.count > 0) continue;
      if (!contains(n, nodes[i + 1]) || !contains(n, nodes[n.offset]))
        fail_section(accel->bvh()->nodes(),
                     name + " node " + std::to_string(i) + " does not contain its children");
    }
    const auto prim_ids = bvh.prim_ids();
    const auto leaf_triangles = bvh.triangles();
    for (std::size_t r = 0; r < prim_ids.size(); ++r) {
      if (prim_ids[r] >= triangles_view.size())
        fail_section(accel->bvh()->prim_ids(), name + " reference " + std::to_string(r) +
                                                   " names triangle " +
                                                   std::to_string(prim_ids[r]));
      const auto& t = triangles_view[prim_ids[r]];
      const format::RayTriangle expected{positions_view[t.v[0]], positions_view[t.v[1]],
                                         positions_view[t.v[2]]};
      if (std::memcmp(&expected, &leaf_triangles[r], sizeof(expected)) != 0)
        fail_section(accel->bvh()->triangles(), name + " reference " + std::to_string(r) +
                                                    " does not match its triangle's corners");
    }
  }
}

// Beyond the view's structural walk: splits inside their cells, the triangle copies equal to the
// scene's, and every triangle in at least one leaf.
void Blob::verify_kdtree(const schema::Acceleration& accel) const {
  const std::string name = accel.kind()->str();
  const auto* desc = accel.kdtree();
  const KdTreeView tree = KdTreeView::from_blob(*this, name);
  const auto positions_view = positions();
  const auto triangles_view = triangles();
  const auto copies = tree.triangles();
  for (std::size_t i = 0; i < triangles_view.size(); ++i) {
    const auto& t = triangles_view[i];
    const format::RayTriangle expected{positions_view[t.v[0]], positions_view[t.v[1]],
                                       positions_view[t.v[2]]};
    if (std::memcmp(&expected, &copies[i], sizeof(expected)) != 0)
      fail_section(desc->triangles(),
                   name + " triangle " + std::to_string(i) + " does not match the scene's corners");
  }
  std::vector<bool> referenced(triangles_view.size());
  for (const auto id : tree.prim_ids()) referenced[id] = true;
  for (std::size_t i = 0; i < referenced.size(); ++i)
    if (!referenced[i])
      fail_section(desc->prim_ids(), name + " triangle " + std::to_string(i) + " is in no leaf");
  walk_cells<format::KdNode>(
      tree.nodes(), tree.bounds_min(), tree.bounds_max(),
      [&](std::uint32_t index, const format::KdNode& n, Cell& below, Cell& above) {
        const auto a = n.axis();
        if (!(n.split() > below.lo[a] && n.split() < below.hi[a]))
          fail_section(desc->nodes(),
                       name + " node " + std::to_string(index) + " splits outside its cell");
        below.hi[a] = above.lo[a] = n.split();
      },
      [](const format::KdNode&, const Cell&) {});
}

// Beyond the view's structural walk: every vertex exactly once, each point a bitwise copy of its
// vertex, the bounds and every gap true of the points below them (searches prune on them).
void Blob::verify_point_tree(const schema::Acceleration& accel) const {
  const std::string name = accel.kind()->str();
  const auto* desc = accel.points();
  const PointTreeView tree = PointTreeView::from_blob(*this, name);
  const auto positions_view = positions();
  const auto ids = tree.ids();
  const auto points = tree.points();
  std::vector<bool> seen(positions_view.size());
  for (std::size_t i = 0; i < ids.size(); ++i) {
    if (ids[i] >= positions_view.size() || seen[ids[i]])
      fail_section(desc->point_ids(), name + " point " + std::to_string(i) + " names vertex " +
                                          std::to_string(ids[i]) + " out of range or twice");
    seen[ids[i]] = true;
    if (std::memcmp(&points[i], &positions_view[ids[i]], sizeof(format::Float3)) != 0)
      fail_section(desc->points(),
                   name + " point " + std::to_string(i) + " does not match its vertex");
  }
  // Walk with the box every point below must lie in: the bounds, narrowed by each gap.
  walk_cells<format::PointNode>(
      tree.nodes(), tree.bounds_min(), tree.bounds_max(),
      [&](std::uint32_t index, const format::PointNode& n, Cell& below, Cell& above) {
        const auto a = n.axis();
        if (!(n.below_max() <= n.above_min()))
          fail_section(desc->nodes(),
                       name + " node " + std::to_string(index) + " has an inverted gap");
        below.hi[a] = std::min(below.hi[a], n.below_max());
        above.lo[a] = std::max(above.lo[a], n.above_min());
      },
      [&](const format::PointNode& n, const Cell& c) {
        for (std::uint32_t i = n.first_point(); i < n.first_point() + n.point_count(); ++i) {
          const float p[3] = {points[i].x, points[i].y, points[i].z};
          for (int a = 0; a < 3; ++a)
            if (!(p[a] >= c.lo[a] && p[a] <= c.hi[a]))
              fail_section(desc->nodes(), name + " point " + std::to_string(i) +
                                              " lies outside the bounds or gaps above it");
        }
      });
}

// Beyond the view's parse: the attachment's codes ascending, each naming a set voxel, one per
// voxel the manifest counts.
void Blob::verify_voxel_dag(const schema::Acceleration& accel) const {
  const std::string name = accel.kind()->str();
  const auto* desc = accel.dag();
  const VoxelDagView dag = VoxelDagView::from_blob(*this, name);
  const auto codes = section_view<std::uint64_t>(desc->voxel_codes());
  for (std::size_t i = 0; i < codes.size(); ++i) {
    const std::uint64_t c = codes[i];
    if ((i > 0 && codes[i - 1] >= c) ||
        !dag.occupied(format::compact_bits(c), format::compact_bits(c >> 1),
                      format::compact_bits(c >> 2)))
      fail_section(desc->voxel_codes(), name + " voxel code " + std::to_string(i) +
                                            " is out of order or names an empty voxel");
  }
}

// Beyond the view's walk (which bounds every pointer and refuses contours without a normal):
// the manifest's counts are the tree's.
void Blob::verify_esvo(const schema::Acceleration& accel) const {
  const std::string name = accel.kind()->str();
  const auto* desc = accel.esvo();
  const EsvoView::Counts counts = EsvoView::from_blob(*this, name).counts();
  if (counts.descriptors != desc->descriptor_count() || counts.voxels != desc->voxel_count() ||
      counts.leaves != desc->leaf_count() || counts.contours != desc->contour_count())
    fail_section(desc->words(), name + " holds " + std::to_string(counts.descriptors) +
                                    " descriptors, " + std::to_string(counts.voxels) + " voxels, " +
                                    std::to_string(counts.leaves) + " leaves, " +
                                    std::to_string(counts.contours) +
                                    " contours; the manifest says otherwise");
}

}  // namespace kiln
