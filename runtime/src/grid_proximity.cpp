// Closest point, point inside and box queries on the uniform and the two-level grid, with the
// semantics and tie rules every triangle structure shares (proximity_detail.hpp).
//
// The builder lists a triangle in every cell whose closed box, padded a little, it meets, so each
// point of a triangle lies in a cell listing it. Hence:
// - box: a point shared by the box and a triangle lies in a cell that lists the triangle and
//   meets the box; the cells meeting the box are found by index ranges with a cell of slack;
// - closest point: cubes around p of growing half-width r are searched; once the best distance is
//   at most r, the closest surface point lies in the cube, so in a searched cell;
// - inside: a crossing of the ray and a triangle lies in a cell the DDA visits.
// Cells are tested with whole triangles; a triangle listed in several cells counts once.
#include <cmath>
#include <cstdint>
#include <vector>

#include "kiln/runtime/grid.hpp"
#include "kiln/runtime/triangle_geometry.hpp"
#include "kiln/runtime/watertight.hpp"
#include "proximity_detail.hpp"

namespace kiln {

using namespace proximity_detail;

namespace {

// Calls fn(list) for every cell of `f` that may meet the closed box; `base` is the first cell's
// index in the lists.
template <class Fn>
void cells_in_box(const GridFrame& f, const GridLists& lists, std::uint64_t base,
                  const format::Box3d& box, Fn&& fn) {
  std::uint32_t first[3], last[3];
  for (int a = 0; a < 3; ++a)
    if (!cell_range(f, a, format::at(box.min, a), format::at(box.max, a), first[a], last[a]))
      return;
  std::uint32_t c[3];
  for (c[2] = first[2]; c[2] <= last[2]; ++c[2])
    for (c[1] = first[1]; c[1] <= last[1]; ++c[1])
      for (c[0] = first[0]; c[0] <= last[0]; ++c[0]) fn(lists.cell(base + f.linear(c)));
}

template <class Fn>
void lists_in_box(const GridView& g, const format::Box3d& box, Fn&& fn) {
  cells_in_box(g.frame(), g.lists(), 0, box, fn);
}

template <class Fn>
void lists_in_box(const NestedGridView& g, const format::Box3d& box, Fn&& fn) {
  const GridFrame& top = g.frame();
  std::uint32_t first[3], last[3];
  for (int a = 0; a < 3; ++a)
    if (!cell_range(top, a, format::at(box.min, a), format::at(box.max, a), first[a], last[a]))
      return;
  std::uint32_t c[3];
  for (c[2] = first[2]; c[2] <= last[2]; ++c[2])
    for (c[1] = first[1]; c[1] <= last[1]; ++c[1])
      for (c[0] = first[0]; c[0] <= last[0]; ++c[0]) {
        const format::LeafGrid& leaf = g.leaves()[top.linear(c)];
        if (leaf.res[0] != 0) cells_in_box(g.leaf_frame(c), g.lists(), leaf.first_cell, box, fn);
      }
}

// Calls fn(list) for every cell the ray (0, inf) crosses.
template <class Fn>
void lists_on_ray(const GridView& g, const GridRay& r, Fn&& fn) {
  walk_grid(g.frame(), r, 0.0f, INFINITY, [&](const std::uint32_t c[3], float, float) {
    fn(g.lists().cell(g.frame().linear(c)));
    return false;
  });
}

template <class Fn>
void lists_on_ray(const NestedGridView& g, const GridRay& r, Fn&& fn) {
  walk_grid(g.frame(), r, 0.0f, INFINITY, [&](const std::uint32_t top[3], float t0, float t1) {
    const format::LeafGrid& leaf = g.leaves()[g.frame().linear(top)];
    if (leaf.res[0] == 0) return false;
    const GridFrame frame = g.leaf_frame(top);
    walk_grid(frame, r, widen_enter(t0), widen_exit(t1),
              [&](const std::uint32_t c[3], float, float) {
                fn(g.lists().cell(leaf.first_cell + frame.linear(c)));
                return false;
              });
    return false;
  });
}

// Whether the cube [p - r, p + r] covers the grid's box.
bool covers(const GridFrame& f, const format::Double3& p, double r) {
  for (int a = 0; a < 3; ++a)
    if (!(format::at(p, a) - r <= f.lo[a] && format::at(p, a) + r >= f.hi[a])) return false;
  return true;
}

template <class G>
ClosestPoint closest(const G& g, const format::Float3& point, float max_distance) {
  ClosestPoint result;
  if (!std::isfinite(point.x) || !std::isfinite(point.y) || !std::isfinite(point.z)) return result;
  const format::Double3 p = to_d(point);
  const GridFrame& f = g.frame();
  double best = double(max_distance) * double(max_distance);
  // Start with a cube reaching the grid's box plus one top cell.
  double r = std::sqrt(box_distance_squared(f.lo, f.hi, p));
  for (int a = 0; a < 3; ++a) r += double(f.hi[a] - f.lo[a]) / f.res[a];
  const auto tris = g.triangles();
  for (;;) {
    const format::Box3d box{{p.x - r, p.y - r, p.z - r}, {p.x + r, p.y + r, p.z + r}};
    lists_in_box(g, box, [&](std::span<const std::uint32_t> refs) {
      for (const std::uint32_t prim : refs) consider_closest(p, tris[prim], prim, best, result);
    });
    if (best <= r * r || covers(f, p, r)) break;
    r *= 2;
  }
  finish_closest(best, result);
  return result;
}

template <class G>
void in_box(const G& g, const format::Float3& lo, const format::Float3& hi,
            std::vector<std::uint32_t>& out) {
  out.clear();
  format::Box3d box;
  if (!prepare_query_box(lo, hi, box)) return;  // empty or NaN box
  const auto tris = g.triangles();
  lists_in_box(g, box, [&](std::span<const std::uint32_t> refs) {
    for (const std::uint32_t prim : refs)
      if (triangle_in_box(tris[prim], box)) out.push_back(prim);
  });
  sort_unique(out);
}

template <class G>
bool inside(const G& g, const format::Float3& p) {
  return inside_by_vote(p, [&](const Ray& ray, std::vector<std::uint32_t>& crossed) {
    crossed.clear();
    const GridRay r = make_grid_ray(ray);
    const WatertightRay tri_ray = prepare_watertight(ray);
    const auto tris = g.triangles();
    lists_on_ray(g, r, [&](std::span<const std::uint32_t> refs) {
      for (const std::uint32_t prim : refs)
        if (ray_crosses(tri_ray, tris[prim])) crossed.push_back(prim);
    });
    sort_unique(crossed);
  });
}

}  // namespace

ClosestPoint closest_point(const GridView& g, const format::Float3& p, float max_distance) {
  return closest(g, p, max_distance);
}
ClosestPoint closest_point(const NestedGridView& g, const format::Float3& p, float max_distance) {
  return closest(g, p, max_distance);
}
void triangles_in_box(const GridView& g, const format::Float3& lo, const format::Float3& hi,
                      std::vector<std::uint32_t>& out) {
  in_box(g, lo, hi, out);
}
void triangles_in_box(const NestedGridView& g, const format::Float3& lo, const format::Float3& hi,
                      std::vector<std::uint32_t>& out) {
  in_box(g, lo, hi, out);
}
bool point_inside(const GridView& g, const format::Float3& p) {
  return inside(g, p);
}
bool point_inside(const NestedGridView& g, const format::Float3& p) {
  return inside(g, p);
}

}  // namespace kiln
