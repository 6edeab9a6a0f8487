// Watertight ray-triangle intersection (Woop, Benthin, Wald, JCGT 2013): the ray is sheared so
// it runs along +z through the origin, and the 2D edge functions decide the hit. Edge functions
// of neighbouring triangles are computed from the same values with the same operations, so a
// ray through a shared edge or vertex hits at least one of them; exact zeros are re-evaluated
// in double.
#pragma once

#include <cmath>

#include "kiln/formats/geometry.hpp"
#include "kiln/runtime/ray.hpp"

namespace kiln {

// Per-ray constants of the test.
struct WatertightRay {
  int kx, ky, kz;
  float sx, sy, sz;
  float org[3];
};

// A point's coordinates as an array, so the permuted axes index instead of branching.
struct Coords {
  float c[3];
  explicit Coords(const format::Float3& p) : c{p.x, p.y, p.z} {}
};

// Without branches: the axis choice is unpredictable for incoherent rays (a mispredicted branch
// or two cost up to a tenth of a cheap ray's time in the wide BVH).
inline WatertightRay prepare_watertight(const Ray& ray) {
  WatertightRay w{};
  const float d[3] = {ray.dir.x, ray.dir.y, ray.dir.z};
  const float ax = std::fabs(d[0]), ay = std::fabs(d[1]), az = std::fabs(d[2]);
  // kz = ax > ay ? (ax > az ? 0 : 2) : (ay > az ? 1 : 2), by table on the three comparisons.
  const unsigned index = unsigned(ax > ay) << 2 | unsigned(ax > az) << 1 | unsigned(ay > az);
  const unsigned kz = 0x00221212u >> (4 * index) & 3u;
  unsigned kx = 0x021u >> (4 * kz) & 3u, ky = 0x102u >> (4 * kz) & 3u;
  const float dz = d[kz];
  // Keep the winding: a negative z-direction swaps x and y.
  const unsigned swap = (kx ^ ky) & (0u - unsigned(dz < 0.0f));
  kx ^= swap, ky ^= swap;
  w.kx = int(kx), w.ky = int(ky), w.kz = int(kz);
  w.sx = d[kx] / dz;
  w.sy = d[ky] / dz;
  w.sz = 1.0f / dz;
  w.org[0] = ray.org.x, w.org[1] = ray.org.y, w.org[2] = ray.org.z;
  return w;
}

// On a hit within (tmin, tmax) writes t and the barycentric weights u (of v1) and v (of v2).
inline bool intersect_watertight(const WatertightRay& r, const format::Float3& v0,
                                 const format::Float3& v1, const format::Float3& v2, float tmin,
                                 float tmax, float& t_out, float& u_out, float& v_out) {
  const Coords a(v0), b(v1), c(v2);
  const float ax0 = a.c[r.kx] - r.org[r.kx], ay0 = a.c[r.ky] - r.org[r.ky],
              az0 = a.c[r.kz] - r.org[r.kz];
  const float bx0 = b.c[r.kx] - r.org[r.kx], by0 = b.c[r.ky] - r.org[r.ky],
              bz0 = b.c[r.kz] - r.org[r.kz];
  const float cx0 = c.c[r.kx] - r.org[r.kx], cy0 = c.c[r.ky] - r.org[r.ky],
              cz0 = c.c[r.kz] - r.org[r.kz];
  const float ax = ax0 - r.sx * az0, ay = ay0 - r.sy * az0;
  const float bx = bx0 - r.sx * bz0, by = by0 - r.sy * bz0;
  const float cx = cx0 - r.sx * cz0, cy = cy0 - r.sy * cz0;
  float u = cx * by - cy * bx;
  float v = ax * cy - ay * cx;
  float w = bx * ay - by * ax;
  if (u == 0.0f || v == 0.0f || w == 0.0f) {
    u = float(double(cx) * double(by) - double(cy) * double(bx));
    v = float(double(ax) * double(cy) - double(ay) * double(cx));
    w = float(double(bx) * double(ay) - double(by) * double(ax));
  }
  if ((u < 0.0f || v < 0.0f || w < 0.0f) && (u > 0.0f || v > 0.0f || w > 0.0f)) return false;
  const float det = u + v + w;
  if (det == 0.0f) return false;
  const float t_scaled = u * (r.sz * az0) + v * (r.sz * bz0) + w * (r.sz * cz0);
  const float t = t_scaled / det;
  if (!(t > tmin && t < tmax)) return false;
  t_out = t;
  u_out = v / det;
  v_out = w / det;
  return true;
}

}  // namespace kiln
