// Ray traversal of the uniform and the two-level grid: the 3D-DDA (grid_dda.hpp) visits cells
// front to back; a cell's triangles are tested against the whole ray with the watertight test
// (so hits equal brute force's bit for bit), and the walk stops after a cell once the best hit
// lies before that cell's exit. A later cell cannot hold a nearer hit: its points lie beyond the
// exit, and the builder pads each cell's list so that rounding in the walk (a neighbour's cell
// at a boundary or corner) never loses a triangle. A triangle listed in several cells may be
// tested more than once; the result is the same.
#include <algorithm>

#include "kiln/runtime/grid.hpp"
#include "kiln/runtime/watertight.hpp"

namespace kiln {

namespace {

// The last triangles tested on this ray (Amanatides & Woo's mailbox, as a small ring): a
// triangle listed in consecutive cells is tested once. Skipping a repeat never changes the
// result, since its test would give the same answer.
struct Mailbox {
  std::uint32_t ids[8] = {kNoHit, kNoHit, kNoHit, kNoHit, kNoHit, kNoHit, kNoHit, kNoHit};
  std::uint32_t next = 0;

  bool seen_or_add(std::uint32_t prim) {
    for (const std::uint32_t id : ids)
      if (id == prim) return true;
    ids[next++ & 7u] = prim;
    return false;
  }
};

// The closest (or, with kAnyHit, any) hit among one cell's triangles, updating `hit`; true when
// an any-hit search is done.
template <bool kAnyHit, bool kCount>
bool test_cell(std::span<const std::uint32_t> refs, std::span<const format::RayTriangle> tris,
               const WatertightRay& tri_ray, float tmin, Hit& hit, Mailbox& mailbox, Cost* cost) {
  for (const std::uint32_t prim : refs) {
    if (mailbox.seen_or_add(prim)) continue;
    if constexpr (kCount) cost->tests += 1;
    const format::RayTriangle& tri = tris[prim];
    float t, u, v;
    if (intersect_watertight(tri_ray, tri.v0, tri.v1, tri.v2, tmin, hit.t, t, u, v)) {
      hit = {t, prim, u, v};
      if constexpr (kAnyHit) return true;
    }
  }
  return false;
}

template <bool kAnyHit, bool kCount>
Hit traverse(const GridView& grid, const Ray& ray, Cost* cost) {
  const GridRay r = make_grid_ray(ray);
  const WatertightRay tri_ray = prepare_watertight(ray);
  Hit hit;
  hit.t = ray.tmax;
  Mailbox mailbox;
  walk_grid(grid.frame(), r, ray.tmin, ray.tmax,
            [&](const std::uint32_t cell[3], float, float t_exit) {
              if constexpr (kCount) cost->nodes += 1;
              const auto refs = grid.lists().cell(grid.frame().linear(cell));
              if (test_cell<kAnyHit, kCount>(refs, grid.triangles(), tri_ray, ray.tmin, hit,
                                             mailbox, cost))
                return true;
              return hit.prim != kNoHit && hit.t <= t_exit;
            });
  return hit.prim == kNoHit ? Hit{} : hit;
}

template <bool kAnyHit, bool kCount>
Hit traverse(const NestedGridView& grid, const Ray& ray, Cost* cost) {
  const GridRay r = make_grid_ray(ray);
  const WatertightRay tri_ray = prepare_watertight(ray);
  Hit hit;
  hit.t = ray.tmax;
  Mailbox mailbox;
  bool done = false;
  walk_grid(grid.frame(), r, ray.tmin, ray.tmax,
            [&](const std::uint32_t top[3], float t_enter, float t_exit) {
              if constexpr (kCount) cost->nodes += 1;
              const format::LeafGrid& leaf = grid.leaves()[grid.frame().linear(top)];
              if (leaf.res[0] == 0) return false;
              const GridFrame frame = grid.leaf_frame(top);
              const float lo = std::max(ray.tmin, widen_enter(t_enter));
              const float hi = std::min(hit.t, widen_exit(t_exit));
              walk_grid(frame, r, lo, hi, [&](const std::uint32_t cell[3], float, float leaf_exit) {
                if constexpr (kCount) cost->nodes += 1;
                const auto refs = grid.lists().cell(leaf.first_cell + frame.linear(cell));
                done = test_cell<kAnyHit, kCount>(refs, grid.triangles(), tri_ray, ray.tmin, hit,
                                                  mailbox, cost) ||
                       (hit.prim != kNoHit && hit.t <= leaf_exit);
                return done;
              });
              return done || (hit.prim != kNoHit && hit.t <= t_exit);
            });
  return hit.prim == kNoHit ? Hit{} : hit;
}

}  // namespace

Hit GridView::intersect(const Ray& ray) const {
  return traverse<false, false>(*this, ray, nullptr);
}
Hit GridView::intersect_counting(const Ray& ray, Cost& cost) const {
  return traverse<false, true>(*this, ray, &cost);
}
Hit GridView::intersect_any(const Ray& ray) const {
  return traverse<true, false>(*this, ray, nullptr);
}
bool GridView::occluded(const Ray& ray) const {
  return traverse<true, false>(*this, ray, nullptr).hit();
}

Hit NestedGridView::intersect(const Ray& ray) const {
  return traverse<false, false>(*this, ray, nullptr);
}
Hit NestedGridView::intersect_counting(const Ray& ray, Cost& cost) const {
  return traverse<false, true>(*this, ray, &cost);
}
Hit NestedGridView::intersect_any(const Ray& ray) const {
  return traverse<true, false>(*this, ray, nullptr);
}
bool NestedGridView::occluded(const Ray& ray) const {
  return traverse<true, false>(*this, ray, nullptr).hit();
}

}  // namespace kiln
