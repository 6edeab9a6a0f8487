// Sutherland-Hodgman clipping of a triangle to an axis-aligned box, in double: the exact piece of
// a triangle inside a cell (perfect splits, contour fitting).
#pragma once

namespace kiln {

struct ClipPoint {
  double c[3];
};

// A triangle clipped by six planes has at most 9 vertices.
struct ClipPolygon {
  ClipPoint v[9];
  int n = 0;
};

// Keeps the part of `in` on the side `keep_above` of the plane x[axis] = d. New vertices get the
// plane's coordinate exactly so rounding cannot push them outside.
inline ClipPolygon clip_by_plane(const ClipPolygon& in, int axis, double d, bool keep_above) {
  ClipPolygon out;
  auto inside = [&](const ClipPoint& p) { return keep_above ? p.c[axis] >= d : p.c[axis] <= d; };
  for (int i = 0; i < in.n; ++i) {
    const ClipPoint& a = in.v[i];
    const ClipPoint& b = in.v[(i + 1) % in.n];
    const bool a_in = inside(a), b_in = inside(b);
    if (a_in) out.v[out.n++] = a;
    if (a_in != b_in) {
      const double t = (d - a.c[axis]) / (b.c[axis] - a.c[axis]);
      ClipPoint p;
      for (int k = 0; k < 3; ++k) p.c[k] = a.c[k] + (b.c[k] - a.c[k]) * t;
      p.c[axis] = d;
      out.v[out.n++] = p;
    }
  }
  return out;
}

// The part of triangle abc inside [lo, hi]; n == 0 when they do not meet.
inline ClipPolygon clip_triangle(const ClipPoint& a, const ClipPoint& b, const ClipPoint& c,
                                 const double lo[3], const double hi[3]) {
  ClipPolygon poly;
  poly.n = 3;
  poly.v[0] = a, poly.v[1] = b, poly.v[2] = c;
  for (int axis = 0; axis < 3 && poly.n > 0; ++axis) {
    poly = clip_by_plane(poly, axis, lo[axis], true);
    if (poly.n > 0) poly = clip_by_plane(poly, axis, hi[axis], false);
  }
  return poly;
}

}  // namespace kiln
