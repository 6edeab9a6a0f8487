// Exact triangle predicates shared by the queries (and later the voxelizer).
#pragma once

#include <algorithm>
#include <cmath>

#include "kiln/formats/geometry.hpp"

namespace kiln {

// Closest point on triangle abc to p (Ericson, Real-Time Collision Detection 5.1.5), in double.
// Returns the barycentric weights (v of b, w of c); handles degenerate triangles.
inline format::Double3 closest_on_triangle(format::Double3 p, format::Double3 a, format::Double3 b,
                                           format::Double3 c, double& v_out, double& w_out) {
  const format::Double3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return v_out = 0, w_out = 0, a;
  const format::Double3 bp = p - b;
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return v_out = 1, w_out = 0, b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return v_out = v, w_out = 0, a + ab * v;
  }
  const format::Double3 cp = p - c;
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return v_out = 0, w_out = 1, c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return v_out = 0, w_out = w, a + ac * w;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return v_out = 1 - w, w_out = w, b + (c - b) * w;
  }
  const double sum = va + vb + vc;
  if (!(sum > 0)) {  // degenerate (collinear) triangle: the nearest of its three edges
    double best = INFINITY;
    format::Double3 result = a;
    const format::Double3 corners[3] = {a, b, c};
    for (int e = 0; e < 3; ++e) {
      const format::Double3 s = corners[e], d = corners[(e + 1) % 3] - s;
      const double len2 = dot(d, d);
      const double t = len2 > 0 ? std::clamp(dot(p - s, d) / len2, 0.0, 1.0) : 0.0;
      const format::Double3 q = s + d * t;
      const double dist = dot(p - q, p - q);
      if (dist < best) {
        best = dist, result = q;
        const double wt[3] = {e == 0   ? 1 - t
                              : e == 2 ? t
                                       : 0,
                              e == 0   ? t
                              : e == 1 ? 1 - t
                                       : 0,
                              e == 1   ? t
                              : e == 2 ? 1 - t
                                       : 0};
        v_out = wt[1], w_out = wt[2];
      }
    }
    return result;
  }
  const double denom = 1 / sum;
  const double v = vb * denom, w = vc * denom;
  return v_out = v, w_out = w, a + ab * v + ac * w;
}

// Triangle-box overlap by the 13 separating axes (Akenine-Moller 2001), in double; touching
// counts as overlapping.
inline bool triangle_overlaps_box(format::Double3 v0, format::Double3 v1, format::Double3 v2,
                                  format::Double3 lo, format::Double3 hi) {
  const format::Double3 center = (lo + hi) * 0.5, half = (hi - lo) * 0.5;
  const format::Double3 a = v0 - center, b = v1 - center, c = v2 - center;
  const double h[3] = {half.x, half.y, half.z};
  // Box face normals.
  for (int i = 0; i < 3; ++i) {
    const double mn = std::min({format::at(a, i), format::at(b, i), format::at(c, i)});
    const double mx = std::max({format::at(a, i), format::at(b, i), format::at(c, i)});
    if (mn > h[i] || mx < -h[i]) return false;
  }
  const format::Double3 edges[3] = {b - a, c - b, a - c};
  const format::Double3 axes[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  auto separated = [&](format::Double3 axis) {
    const double pa = dot(a, axis), pb = dot(b, axis), pc = dot(c, axis);
    const double r = h[0] * std::fabs(axis.x) + h[1] * std::fabs(axis.y) + h[2] * std::fabs(axis.z);
    return std::min({pa, pb, pc}) > r || std::max({pa, pb, pc}) < -r;
  };
  // Edge x box-axis cross products.
  for (const format::Double3& e : edges)
    for (const format::Double3& u : axes)
      if (separated(cross(u, e))) return false;
  // Triangle normal.
  return !separated(cross(edges[0], edges[1]));
}

}  // namespace kiln
