// Exact triangle predicates shared by the queries (and later the voxelizer).
#pragma once

#include <algorithm>
#include <cmath>

#include "kiln/formats/geometry.hpp"

namespace kiln {

struct Vec3d {
  double x, y, z;
};
inline Vec3d to_d(const format::Float3& p) {
  return {p.x, p.y, p.z};
}
inline format::Float3 to_f(const Vec3d& p) {
  return {float(p.x), float(p.y), float(p.z)};
}
inline Vec3d operator-(Vec3d a, Vec3d b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
inline Vec3d operator+(Vec3d a, Vec3d b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z};
}
inline Vec3d operator*(Vec3d a, double s) {
  return {a.x * s, a.y * s, a.z * s};
}
inline double dot(Vec3d a, Vec3d b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
inline Vec3d cross(Vec3d a, Vec3d b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline Vec3d normalize(Vec3d a) {
  return a * (1.0 / std::sqrt(dot(a, a)));
}

// Closest point on triangle abc to p (Ericson, Real-Time Collision Detection 5.1.5), in double.
// Returns the barycentric weights (v of b, w of c); handles degenerate triangles.
inline Vec3d closest_on_triangle(Vec3d p, Vec3d a, Vec3d b, Vec3d c, double& v_out, double& w_out) {
  const Vec3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return v_out = 0, w_out = 0, a;
  const Vec3d bp = p - b;
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return v_out = 1, w_out = 0, b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return v_out = v, w_out = 0, a + ab * v;
  }
  const Vec3d cp = p - c;
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
    Vec3d result = a;
    const Vec3d corners[3] = {a, b, c};
    for (int e = 0; e < 3; ++e) {
      const Vec3d s = corners[e], d = corners[(e + 1) % 3] - s;
      const double len2 = dot(d, d);
      const double t = len2 > 0 ? std::clamp(dot(p - s, d) / len2, 0.0, 1.0) : 0.0;
      const Vec3d q = s + d * t;
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
inline bool triangle_overlaps_box(Vec3d v0, Vec3d v1, Vec3d v2, Vec3d lo, Vec3d hi) {
  const Vec3d center = (lo + hi) * 0.5, half = (hi - lo) * 0.5;
  const Vec3d a = v0 - center, b = v1 - center, c = v2 - center;
  const double h[3] = {half.x, half.y, half.z};
  auto comp = [](const Vec3d& v, int i) { return i == 0 ? v.x : i == 1 ? v.y : v.z; };
  // Box face normals.
  for (int i = 0; i < 3; ++i) {
    const double mn = std::min({comp(a, i), comp(b, i), comp(c, i)});
    const double mx = std::max({comp(a, i), comp(b, i), comp(c, i)});
    if (mn > h[i] || mx < -h[i]) return false;
  }
  const Vec3d edges[3] = {b - a, c - b, a - c};
  const Vec3d axes[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  auto separated = [&](Vec3d axis) {
    const double pa = dot(a, axis), pb = dot(b, axis), pc = dot(c, axis);
    const double r = h[0] * std::fabs(axis.x) + h[1] * std::fabs(axis.y) + h[2] * std::fabs(axis.z);
    return std::min({pa, pb, pc}) > r || std::max({pa, pb, pc}) < -r;
  };
  // Edge x box-axis cross products.
  for (const Vec3d& e : edges)
    for (const Vec3d& u : axes)
      if (separated(cross(u, e))) return false;
  // Triangle normal.
  return !separated(cross(edges[0], edges[1]));
}

}  // namespace kiln
