// Closest point, point inside and box queries on the SAH k-d tree, with the semantics and tie
// rules every triangle structure shares (proximity_detail.hpp).
//
// Every walk starts from the root cell (the tree's bounds, which hold every triangle) and cuts the
// current cell at each interior node's plane, so the leaf cells tile the root box. The builder
// puts a triangle in every leaf whose closed cell its surface meets (clipped bounds rounded
// outwards), so each point of a triangle lies in the cell of some leaf that references it. Hence:
// - closest point: the closest surface point q lies in a leaf cell referencing its triangle, and
//   that cell's distance to p is at most |p - q|, so pruning cells farther than the best so far
//   never loses it; a point outside the root box works the same way, its cell distances growing
//   from the root's;
// - box: a point shared by the box and a triangle lies in a leaf cell that references the
//   triangle and overlaps the box;
// - inside: a crossing of the ray and a triangle lies in a leaf cell the ray touches, and the
//   conservative slab test never rejects a cell the ray touches.
// Leaves are tested with whole triangles (KdTreeView::triangles() by primitive id), never the
// part inside the cell; a triangle met in several leaves counts once.
#include <cstdint>
#include <utility>
#include <vector>

#include "kiln/runtime/kdtree.hpp"
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

Cell root_cell(const KdTreeView& tree) {
  Cell c;
  for (int a = 0; a < 3; ++a)
    c.lo[a] = format::at(tree.bounds().min, a), c.hi[a] = format::at(tree.bounds().max, a);
  return c;
}

// The cells of an interior node's below (first) and above (second) children.
std::pair<Cell, Cell> split_cell(const Cell& cell, const format::KdNode& n) {
  std::pair<Cell, Cell> children{cell, cell};
  children.first.hi[n.axis()] = n.split();
  children.second.lo[n.axis()] = n.split();
  return children;
}

// Calls leaf(node) for every leaf whose cell passes `enter`, depth first. Only the farther child
// of a node on the current path waits on the stack, one per level below the root at most: the
// validated depth (<= kKdMaxDepth levels) bounds it.
template <class Enter, class Leaf>
void walk_cells(const KdTreeView& tree, Enter enter, Leaf leaf) {
  const auto nodes = tree.nodes();
  struct Entry {
    std::uint32_t node;
    Cell cell;
  };
  Entry stack[format::kKdMaxDepth];
  std::uint32_t top = 0;
  Entry current{0, root_cell(tree)};
  if (!enter(current.cell)) return;
  for (;;) {
    const format::KdNode n = nodes[current.node];
    if (!n.is_leaf()) {
      const auto [below, above] = split_cell(current.cell, n);
      const bool enter_below = enter(below), enter_above = enter(above);
      if (enter_below && enter_above) stack[top++] = {n.above_child(), above};
      if (enter_below || enter_above) {
        current = enter_below ? Entry{current.node + 1, below} : Entry{n.above_child(), above};
        continue;
      }
    } else {
      leaf(n);
    }
    if (top == 0) return;
    current = stack[--top];
  }
}

// Sorted, distinct primitive ids of the triangles passing `keep` in every leaf whose cell passes
// `enter`.
template <class Enter, class Keep>
void collect_prims(const KdTreeView& tree, Enter enter, Keep keep,
                   std::vector<std::uint32_t>& out) {
  out.clear();
  const auto prim_ids = tree.prim_ids();
  const auto triangles = tree.triangles();
  walk_cells(tree, enter, [&](const format::KdNode& n) {
    for (std::uint32_t i = n.first_reference(), end = i + n.reference_count(); i < end; ++i)
      if (keep(triangles[prim_ids[i]])) out.push_back(prim_ids[i]);
  });
  sort_unique(out);
}

}  // namespace

ClosestPoint closest_point(const KdTreeView& tree, const format::Float3& point,
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
  // As walk_cells, but nearer child first and cells pruned by distance.
  Entry stack[format::kKdMaxDepth];
  std::uint32_t top = 0;
  Entry current = entry(0, root_cell(tree));
  for (;;) {
    if (current.d2 <= best) {
      const format::KdNode n = nodes[current.node];
      if (!n.is_leaf()) {
        const auto [below, above] = split_cell(current.cell, n);
        Entry near = entry(current.node + 1, below), far = entry(n.above_child(), above);
        if (near.d2 > far.d2) std::swap(near, far);
        if (far.d2 <= best) stack[top++] = far;
        current = near;
        continue;
      }
      for (std::uint32_t i = n.first_reference(), end = i + n.reference_count(); i < end; ++i)
        consider_closest(p, triangles[prim_ids[i]], prim_ids[i], best, result);
    }
    if (top == 0) break;
    current = stack[--top];
  }
  finish_closest(best, result);
  return result;
}

void triangles_in_box(const KdTreeView& tree, const format::Float3& lo_f,
                      const format::Float3& hi_f, std::vector<std::uint32_t>& out) {
  out.clear();
  format::Box3d box;
  if (!prepare_query_box(lo_f, hi_f, box)) return;  // empty or NaN box
  collect_prims(
      tree, [&](const Cell& c) { return box_overlaps(c.lo, c.hi, box); },
      [&](const format::RayTriangle& t) { return triangle_in_box(t, box); }, out);
}

bool point_inside(const KdTreeView& tree, const format::Float3& p) {
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
