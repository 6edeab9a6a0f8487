// Perfect splits need the exact extent of a triangle inside a cell, not its box's overlap.
#include <cmath>

#include "kiln/compiler/kdtree_builder.hpp"

namespace kiln {

namespace {

struct Point {
  double c[3];
};

// A triangle clipped by six planes has at most 9 vertices.
struct Polygon {
  Point v[9];
  int n = 0;
};

// Keeps the part of `in` on the side `keep_above` of the plane x[axis] = d. New vertices get the
// plane's coordinate exactly so rounding cannot push them outside.
Polygon clip(const Polygon& in, int axis, double d, bool keep_above) {
  Polygon out;
  auto inside = [&](const Point& p) { return keep_above ? p.c[axis] >= d : p.c[axis] <= d; };
  for (int i = 0; i < in.n; ++i) {
    const Point& a = in.v[i];
    const Point& b = in.v[(i + 1) % in.n];
    const bool a_in = inside(a), b_in = inside(b);
    if (a_in) out.v[out.n++] = a;
    if (a_in != b_in) {
      const double t = (d - a.c[axis]) / (b.c[axis] - a.c[axis]);
      Point p;
      for (int k = 0; k < 3; ++k) p.c[k] = a.c[k] + (b.c[k] - a.c[k]) * t;
      p.c[axis] = d;
      out.v[out.n++] = p;
    }
  }
  return out;
}

float round_down(double x) {
  const auto f = float(x);
  return double(f) > x ? std::nextafter(f, -INFINITY) : f;
}

float round_up(double x) {
  const auto f = float(x);
  return double(f) < x ? std::nextafter(f, INFINITY) : f;
}

}  // namespace

Aabb clip_triangle_to_box(const format::Float3& a, const format::Float3& b,
                          const format::Float3& c, const Aabb& cell) {
  Polygon poly;
  poly.n = 3;
  poly.v[0] = {{a.x, a.y, a.z}};
  poly.v[1] = {{b.x, b.y, b.z}};
  poly.v[2] = {{c.x, c.y, c.z}};
  for (int axis = 0; axis < 3 && poly.n > 0; ++axis) {
    poly = clip(poly, axis, cell.lo[axis], true);
    if (poly.n > 0) poly = clip(poly, axis, cell.hi[axis], false);
  }
  Aabb box;
  if (poly.n == 0) return box;
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int i = 0; i < poly.n; ++i)
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], poly.v[i].c[k]), hi[k] = std::max(hi[k], poly.v[i].c[k]);
  for (int k = 0; k < 3; ++k) {
    box.lo[k] = std::max(round_down(lo[k]), cell.lo[k]);
    box.hi[k] = std::min(round_up(hi[k]), cell.hi[k]);
  }
  return box;
}

}  // namespace kiln
