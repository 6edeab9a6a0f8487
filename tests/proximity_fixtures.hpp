// Brute-force references and seeded inputs shared by the proximity tests of every structure
// (proximity_test.cpp for the BVH, kdtree_proximity_test.cpp for the k-d tree).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "kiln/compiler/scene.hpp"
#include "kiln/runtime/triangle_geometry.hpp"

namespace kiln::test {

inline format::Double3 corner(const Scene& s, std::uint32_t prim, int k) {
  return to_d(s.positions[s.triangles[prim].v[k]]);
}

// Distance from p to triangle `prim`, as the queries compute it (in double).
inline double triangle_distance(const Scene& s, std::uint32_t prim, const format::Float3& p) {
  double v, w;
  const format::Double3 q = closest_on_triangle(to_d(p), corner(s, prim, 0), corner(s, prim, 1),
                                                corner(s, prim, 2), v, w);
  return std::sqrt(dot(q - to_d(p), q - to_d(p)));
}

inline double brute_closest(const Scene& s, const format::Float3& p) {
  double best = INFINITY;
  for (std::uint32_t i = 0; i < s.triangles.size(); ++i)
    best = std::min(best, triangle_distance(s, i, p));
  return best;
}

// Generalised winding number (sum of signed solid angles, Van Oosterom & Strackee 1983).
inline double winding_number(const Scene& s, const format::Float3& p) {
  double total = 0;
  for (std::uint32_t i = 0; i < s.triangles.size(); ++i) {
    const format::Double3 a = corner(s, i, 0) - to_d(p), b = corner(s, i, 1) - to_d(p),
                          c = corner(s, i, 2) - to_d(p);
    const double la = std::sqrt(dot(a, a)), lb = std::sqrt(dot(b, b)), lc = std::sqrt(dot(c, c));
    const double numerator = dot(a, cross(b, c));
    const double denominator = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
    total += 2 * std::atan2(numerator, denominator);
  }
  return total / (4 * 3.14159265358979323846);
}

// Every triangle overlapping the box, by the same exact test, in id order.
inline std::vector<std::uint32_t> brute_box(const Scene& s, const format::Float3& lo,
                                            const format::Float3& hi) {
  std::vector<std::uint32_t> ids;
  for (std::uint32_t i = 0; i < s.triangles.size(); ++i)
    if (triangle_overlaps_box(corner(s, i, 0), corner(s, i, 1), corner(s, i, 2), to_d(lo),
                              to_d(hi)))
      ids.push_back(i);
  return ids;
}

// Seeded points: uniform in the bounds grown by 25 % (near and far), plus points just off the
// surface on both sides (1e-3 of the diagonal along the face normal).
inline std::vector<format::Float3> sample_points(const Scene& s, std::size_t count,
                                                 std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  const format::Double3 lo = to_d(s.bounds.min), hi = to_d(s.bounds.max), size = hi - lo;
  const double diagonal = std::sqrt(dot(size, size));
  std::vector<format::Float3> points;
  for (std::size_t i = 0; i < count; ++i) {
    format::Double3 p;
    if (i % 2 == 0) {
      p = lo - size * 0.25 +
          format::Double3{size.x * 1.5 * unit(rng), size.y * 1.5 * unit(rng),
                          size.z * 1.5 * unit(rng)};
    } else {
      const auto prim = std::uint32_t(unit(rng) * double(s.triangles.size())) % s.triangles.size();
      double r1 = unit(rng), r2 = unit(rng);
      if (r1 + r2 > 1) r1 = 1 - r1, r2 = 1 - r2;
      const format::Double3 a = corner(s, prim, 0), b = corner(s, prim, 1), c = corner(s, prim, 2);
      format::Double3 n = cross(b - a, c - a);
      n = n * (1 / std::sqrt(dot(n, n)));
      p = a + (b - a) * r1 + (c - a) * r2 + n * ((i % 4 == 1 ? 1e-3 : -1e-3) * diagonal);
    }
    points.push_back(to_f(p));
  }
  return points;
}

struct QueryBox {
  format::Float3 lo, hi;
};

// Seeded boxes around the scene: large and small ones centred in the bounds; every fifth centred
// on a face of the bounds (partly outside); every seventh flat on one axis, its plane through a
// vertex (so triangles touch it exactly).
inline std::vector<QueryBox> query_boxes(const Scene& s, int count, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  const format::Double3 lo = to_d(s.bounds.min), hi = to_d(s.bounds.max), size = hi - lo;
  std::vector<QueryBox> boxes;
  for (int q = 0; q < count; ++q) {
    const double extent = q % 3 == 0 ? 0.3 : 0.05;
    format::Double3 c =
        lo + format::Double3{size.x * unit(rng), size.y * unit(rng), size.z * unit(rng)};
    format::Double3 half{size.x * extent * unit(rng), size.y * extent * unit(rng),
                         size.z * extent * unit(rng)};
    if (q % 5 == 4) format::at(c, q % 3) = format::at(unit(rng) < 0.5 ? lo : hi, q % 3);
    if (q % 7 == 3) {
      const int axis = (q / 7) % 3;
      const auto prim = std::uint32_t(unit(rng) * double(s.triangles.size())) % s.triangles.size();
      c = corner(s, prim, q % 3);
      format::at(half, axis) = 0;
    }
    boxes.push_back({to_f(c - half), to_f(c + half)});
  }
  return boxes;
}

}  // namespace kiln::test
