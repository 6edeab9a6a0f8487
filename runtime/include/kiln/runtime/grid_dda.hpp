// The 3D digital differential analyser of Amanatides & Woo ("A Fast Voxel Traversal Algorithm
// for Ray Tracing", 1987) over one uniform grid: the cells a ray crosses, in order, with the
// parameter at which it leaves each. Shared by the uniform grid and both levels of the two-level
// grid, and by the builders (cell ranges of boxes).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "kiln/formats/grid.hpp"
#include "kiln/runtime/ray.hpp"

namespace kiln {

/// One uniform grid: its box and resolution (each axis >= 1). Cell (x, y, z) spans planes
/// x..x+1, y..y+1, z..z+1 of format::grid_plane.
struct GridFrame {
  float lo[3], hi[3];
  std::uint32_t res[3];

  float plane(int axis, std::uint32_t i) const {
    return format::grid_plane(lo[axis], hi[axis], i, res[axis]);
  }
  std::uint64_t cell_count() const { return std::uint64_t(res[0]) * res[1] * res[2]; }
  std::uint64_t linear(const std::uint32_t c[3]) const {
    return c[0] + std::uint64_t(res[0]) * (c[1] + std::uint64_t(res[1]) * c[2]);
  }
  /// The cell holding coordinate x along `axis`, clamped into the grid (NaN gives 0). Rounding
  /// may give a neighbour of the exact cell; the builder pads cell lists to absorb that.
  std::uint32_t cell_of(int axis, float x) const {
    const float extent = hi[axis] - lo[axis];
    const float scaled = (x - lo[axis]) / extent * float(res[axis]);
    if (!(scaled >= 0.0f)) return 0;
    if (scaled >= float(res[axis])) return res[axis] - 1;
    return std::min(std::uint32_t(scaled), res[axis] - 1);
  }
  /// The sub-grid of one cell: its box, at resolution `r`.
  GridFrame cell_frame(const std::uint32_t c[3], const std::uint32_t r[3]) const {
    GridFrame f{};
    for (int a = 0; a < 3; ++a) {
      f.lo[a] = plane(a, c[a]), f.hi[a] = plane(a, c[a] + 1), f.res[a] = r[a];
    }
    return f;
  }
};

/// A ray's constants for the walk.
struct GridRay {
  float org[3], dir[3], inv_dir[3];
};

inline GridRay make_grid_ray(const Ray& ray) {
  GridRay g{{ray.org.x, ray.org.y, ray.org.z}, {ray.dir.x, ray.dir.y, ray.dir.z}, {}};
  for (int a = 0; a < 3; ++a) g.inv_dir[a] = 1.0f / g.dir[a];
  return g;
}

// Relative padding of slab distances (pbrt-v4's 1 + 2 gamma(3)): rounding never shortens a
// ray's stay in a box.
inline constexpr float kGridFarScale = 1.0f + 2.0f * (3.0f * 0x1p-24f) / (1.0f - 3.0f * 0x1p-24f);

/// A cell's [t_enter, t_exit] widened by their rounding bound, for the walk of a grid inside the
/// cell (which clips to the cell's box again).
inline float widen_enter(float t) {
  return t < 0.0f ? t * kGridFarScale : t * (2.0f - kGridFarScale);
}
inline float widen_exit(float t) {
  return t < 0.0f ? t * (2.0f - kGridFarScale) : t * kGridFarScale;
}

/// Narrows [tmin, tmax] to the part of the ray inside the frame's box, conservatively; false when
/// nothing is left. A NaN slab distance leaves its axis unconstrained.
inline bool clip_to_frame(const GridFrame& f, const GridRay& r, float& tmin, float& tmax) {
  for (int a = 0; a < 3; ++a) {
    const bool negative = r.inv_dir[a] < 0.0f;
    const float near = ((negative ? f.hi[a] : f.lo[a]) - r.org[a]) * r.inv_dir[a];
    const float far = ((negative ? f.lo[a] : f.hi[a]) - r.org[a]) * r.inv_dir[a];
    const float near_padded = near < 0.0f ? near * kGridFarScale : near * (2.0f - kGridFarScale);
    const float far_padded = far < 0.0f ? far * (2.0f - kGridFarScale) : far * kGridFarScale;
    tmin = near_padded > tmin ? near_padded : tmin;
    tmax = far_padded < tmax ? far_padded : tmax;
  }
  return tmin <= tmax;
}

/// Calls visit(cell[3], t_enter, t_exit) for the cells the ray crosses in [tmin, tmax], in order,
/// until it returns true (stop). The ray is clipped to the grid's box first; t_exit is where the
/// ray leaves the cell (or tmax). Each step moves one axis one cell in the ray's direction, so the
/// walk ends after at most res_x + res_y + res_z cells, whatever the floats.
template <class Visit>
void walk_grid(const GridFrame& f, const GridRay& r, float tmin, float tmax, Visit&& visit) {
  if (!clip_to_frame(f, r, tmin, tmax)) return;
  std::uint32_t cell[3];
  int step[3];
  float t_next[3], size[3];
  // The crossing of the plane ahead on `axis`, computed from the plane, never accumulated, so
  // errors never add up along the walk.
  auto crossing = [&](int a) {
    const std::uint32_t ahead = cell[a] + (step[a] > 0);
    return (format::grid_plane_at(f.lo[a], f.hi[a], size[a], ahead, f.res[a]) - r.org[a]) *
           r.inv_dir[a];
  };
  for (int a = 0; a < 3; ++a) {
    size[a] = format::grid_cell_size(f.lo[a], f.hi[a], f.res[a]);
    cell[a] = f.cell_of(a, r.org[a] + r.dir[a] * tmin);
    step[a] = r.dir[a] > 0.0f ? 1 : r.dir[a] < 0.0f ? -1 : 0;
    t_next[a] = step[a] == 0 ? INFINITY : crossing(a);
  }
  float t_enter = tmin;
  for (;;) {
    const int axis = t_next[0] <= t_next[1] ? (t_next[0] <= t_next[2] ? 0 : 2)
                                            : (t_next[1] <= t_next[2] ? 1 : 2);
    const float t_exit = std::min(t_next[axis], tmax);
    if (visit(cell, t_enter, t_exit)) return;
    if (!(t_next[axis] < tmax) || step[axis] == 0) return;
    if (step[axis] > 0 ? cell[axis] + 1 >= f.res[axis] : cell[axis] == 0) return;
    cell[axis] += std::uint32_t(step[axis]);
    t_enter = std::max(t_enter, t_exit);
    t_next[axis] = crossing(axis);
  }
}

/// The range [first, last] of cells along `axis` that may meet [lo, hi] (one cell of slack on
/// each side for rounding); false when [lo, hi] misses the grid's box or is NaN.
inline bool cell_range(const GridFrame& f, int axis, double lo, double hi, std::uint32_t& first,
                       std::uint32_t& last) {
  if (!(lo <= double(f.hi[axis]) && hi >= double(f.lo[axis]))) return false;
  first = f.cell_of(axis, float(lo));
  last = f.cell_of(axis, float(hi));
  first = first > 0 ? first - 1 : 0;
  last = std::min(last + 1, f.res[axis] - 1);
  return true;
}

}  // namespace kiln
