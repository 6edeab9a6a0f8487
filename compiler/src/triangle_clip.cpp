// Perfect splits need the exact extent of a triangle inside a cell, not its box's overlap.
#include <cmath>

#include "kiln/compiler/triangle_clip.hpp"
#include "polygon_clip.hpp"

namespace kiln {

namespace {

float round_down(double x) {
  const auto f = float(x);
  return double(f) > x ? std::nextafter(f, -INFINITY) : f;
}

float round_up(double x) {
  const auto f = float(x);
  return double(f) < x ? std::nextafter(f, INFINITY) : f;
}

}  // namespace

format::Box3f clip_triangle_to_box(const format::Float3& a, const format::Float3& b,
                                   const format::Float3& c, const format::Box3f& cell) {
  const double cell_lo[3] = {cell.min.x, cell.min.y, cell.min.z};
  const double cell_hi[3] = {cell.max.x, cell.max.y, cell.max.z};
  const ClipPolygon poly =
      clip_triangle({{a.x, a.y, a.z}}, {{b.x, b.y, b.z}}, {{c.x, c.y, c.z}}, cell_lo, cell_hi);
  format::Box3f box;
  if (poly.n == 0) return box;
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int i = 0; i < poly.n; ++i)
    for (int k = 0; k < 3; ++k)
      lo[k] = std::min(lo[k], poly.v[i].c[k]), hi[k] = std::max(hi[k], poly.v[i].c[k]);
  for (int k = 0; k < 3; ++k) {
    format::at(box.min, k) = std::max(round_down(lo[k]), format::at(cell.min, k));
    format::at(box.max, k) = std::min(round_up(hi[k]), format::at(cell.max, k));
  }
  return box;
}

}  // namespace kiln
