// Closest point, point inside and box queries on the octree, with the semantics and tie rules
// every triangle structure shares (proximity_detail.hpp).
//
// Every walk starts from the root cell (which holds every triangle) and cuts each interior
// node's cell at its centre (format::octree_child_cell, as the builder did), so the cells of the
// leaves and of the absent octants tile the root cell, and the builder put a triangle in every
// child cell its surface meets (closed cells, exact separating-axis test). Hence:
// - closest point: the closest surface point q lies in a leaf cell referencing its triangle, and
//   that cell's distance to p is at most |p - q|, so pruning cells farther than the best so far
//   never loses it;
// - box: a point shared by the box and a triangle lies in a leaf cell that references the
//   triangle and overlaps the box;
// - inside: a crossing of the ray and a triangle lies in a leaf cell the ray touches, and the
//   conservative slab test never rejects a cell the ray touches.
// Leaves are tested with whole triangles; a triangle met in several leaves counts once.
#include <algorithm>
#include <bit>
#include <cstdint>
#include <vector>

#include "kiln/runtime/octree.hpp"
#include "kiln/runtime/triangle_geometry.hpp"
#include "kiln/runtime/watertight.hpp"
#include "proximity_detail.hpp"
#include "ray_box.hpp"

namespace kiln {

using namespace proximity_detail;

namespace {

struct Cell {
  float lo[3], hi[3];
};

Cell to_cell(const format::Box3f& b) {
  Cell c;
  for (int a = 0; a < 3; ++a) c.lo[a] = format::at(b.min, a), c.hi[a] = format::at(b.max, a);
  return c;
}

format::Box3f to_box(const Cell& c) {
  return {{c.lo[0], c.lo[1], c.lo[2]}, {c.hi[0], c.hi[1], c.hi[2]}};
}

// Expanding a node replaces it by at most eight children: seven more per level.
constexpr std::uint32_t kStackSize = 7 * format::kOctreeMaxDepth + 8;

// Calls leaf(node) for every leaf whose cell passes `enter`, depth first.
template <class Enter, class Leaf>
void walk_cells(const OctreeView& tree, Enter enter, Leaf leaf) {
  struct Entry {
    std::uint32_t node;
    Cell cell;
  };
  Entry stack[kStackSize];
  std::uint32_t top = 0;
  const Cell root = to_cell(tree.bounds());
  if (enter(root)) stack[top++] = {0, root};
  while (top > 0) {
    const Entry e = stack[--top];
    const format::OctreeNode n = tree.nodes()[e.node];
    if (n.is_leaf()) {
      leaf(n);
      continue;
    }
    std::uint32_t child = n.first_child();
    for (std::uint32_t octant = 0; octant < 8; ++octant) {
      if ((n.child_mask() >> octant & 1u) == 0) continue;
      const Cell c = to_cell(format::octree_child_cell(to_box(e.cell), octant));
      if (enter(c)) stack[top++] = {child, c};
      ++child;
    }
  }
}

// Sorted, distinct primitive ids of the triangles passing `keep` in every leaf whose cell passes
// `enter`.
template <class Enter, class Keep>
void collect_prims(const OctreeView& tree, Enter enter, Keep keep,
                   std::vector<std::uint32_t>& out) {
  out.clear();
  const auto prim_ids = tree.prim_ids();
  const auto triangles = tree.triangles();
  walk_cells(tree, enter, [&](const format::OctreeNode& n) {
    for (std::uint32_t i = n.first_reference(), end = i + n.reference_count(); i < end; ++i)
      if (keep(triangles[prim_ids[i]])) out.push_back(prim_ids[i]);
  });
  sort_unique(out);
}

}  // namespace

ClosestPoint closest_point(const OctreeView& tree, const format::Float3& point,
                           float max_distance) {
  const auto nodes = tree.nodes();
  const auto prim_ids = tree.prim_ids();
  const auto triangles = tree.triangles();
  const format::Double3 p = to_d(point);
  double best = double(max_distance) * double(max_distance);
  ClosestPoint result;
  struct Entry {
    std::uint32_t node;
    double d2;  // squared distance from p to the cell
    Cell cell;
  };
  auto entry = [&](std::uint32_t node, const Cell& cell) {
    return Entry{node, box_distance_squared(cell.lo, cell.hi, p), cell};
  };
  // As walk_cells, but children pushed farthest first (nearest expanded next), pruned by
  // distance when pushed and again when popped.
  Entry stack[kStackSize];
  std::uint32_t top = 0;
  stack[top++] = entry(0, to_cell(tree.bounds()));
  while (top > 0) {
    const Entry e = stack[--top];
    if (e.d2 > best) continue;
    const format::OctreeNode n = nodes[e.node];
    if (n.is_leaf()) {
      for (std::uint32_t i = n.first_reference(), end = i + n.reference_count(); i < end; ++i)
        consider_closest(p, triangles[prim_ids[i]], prim_ids[i], best, result);
      continue;
    }
    Entry children[8];
    int count = 0;
    std::uint32_t child = n.first_child();
    for (std::uint32_t octant = 0; octant < 8; ++octant) {
      if ((n.child_mask() >> octant & 1u) == 0) continue;
      const Entry c = entry(child++, to_cell(format::octree_child_cell(to_box(e.cell), octant)));
      if (c.d2 > best) continue;
      int i = count++;
      for (; i > 0 && children[i - 1].d2 < c.d2; --i) children[i] = children[i - 1];
      children[i] = c;
    }
    for (int i = 0; i < count; ++i) stack[top++] = children[i];
  }
  finish_closest(best, result);
  return result;
}

void triangles_in_box(const OctreeView& tree, const format::Float3& lo_f,
                      const format::Float3& hi_f, std::vector<std::uint32_t>& out) {
  out.clear();
  format::Box3d box;
  if (!prepare_query_box(lo_f, hi_f, box)) return;  // empty or NaN box
  collect_prims(
      tree, [&](const Cell& c) { return box_overlaps(c.lo, c.hi, box); },
      [&](const format::RayTriangle& t) { return triangle_in_box(t, box); }, out);
}

bool point_inside(const OctreeView& tree, const format::Float3& p) {
  return inside_by_vote(p, [&](const Ray& ray, std::vector<std::uint32_t>& crossed) {
    const BoxRay box_ray = prepare_box_ray(ray);
    const WatertightRay tri_ray = prepare_watertight(ray);
    collect_prims(
        tree,
        [&](const Cell& c) {
          float tmin = 0.0f, tmax = INFINITY;
          return clip_to_box(c.lo, c.hi, box_ray, tmin, tmax);
        },
        [&](const format::RayTriangle& t) { return ray_crosses(tri_ray, t); }, crossed);
  });
}

}  // namespace kiln
