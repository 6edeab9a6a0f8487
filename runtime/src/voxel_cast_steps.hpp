// The steps of front-to-back ray casting in a voxel grid (voxel = unit cube) that the voxel DAG
// and the SSVDAG share: the ray in grid space, slab tests on integer boxes, children ordered by
// entry distance, and the walk through a 4x4x4 leaf mask. Both casts give the same hits because
// they take the same steps.
#pragma once

#include <algorithm>
#include <bit>
#include <cstdint>

#include "kiln/runtime/ray.hpp"
#include "kiln/runtime/voxel_grid.hpp"

namespace kiln::voxel_cast {

struct GridRay {
  float org[3], inv_dir[3];
  float tmin, tmax;
  bool negative[3];
};

// Entry distance of the ray into the box [lo, lo + size]^3 within [tmin, tmax] and the axis
// whose face it enters through (-1: it starts inside); false when it misses.
inline bool enter(const GridRay& r, std::uint32_t x, std::uint32_t y, std::uint32_t z,
                  std::uint32_t size, float& t_enter, int& axis) {
  const float lo[3] = {float(x), float(y), float(z)};
  float t_near = r.tmin, t_far = r.tmax;
  axis = -1;
  for (int a = 0; a < 3; ++a) {
    float t0 = (lo[a] - r.org[a]) * r.inv_dir[a];
    float t1 = (lo[a] + float(size) - r.org[a]) * r.inv_dir[a];
    if (r.negative[a]) std::swap(t0, t1);
    if (t0 > t_near) t_near = t0, axis = a;
    if (t1 < t_far) t_far = t1;
  }
  t_enter = t_near;
  return t_near <= t_far;
}

struct Candidate {
  float t;
  int axis;
  std::uint32_t index;  // octant, or bit
};

// The present children (bits of `mask`) the ray enters, nearest first.
inline int order_children(const GridRay& r, std::uint32_t mask, std::uint32_t x, std::uint32_t y,
                          std::uint32_t z, std::uint32_t half, Candidate out[8]) {
  int count = 0;
  for (std::uint32_t octant = 0; octant < 8; ++octant) {
    if ((mask >> octant & 1) == 0) continue;
    Candidate c{0, -1, octant};
    if (!enter(r, x + (octant & 1) * half, y + (octant >> 1 & 1) * half,
               z + (octant >> 2 & 1) * half, half, c.t, c.axis))
      continue;
    int i = count++;
    for (; i > 0 && out[i - 1].t > c.t; --i) out[i] = out[i - 1];
    out[i] = c;
  }
  return count;
}

// The ray in grid space (voxel = unit cube); t stays the world-space ray parameter.
inline GridRay grid_ray(const Ray& ray, const VoxelGridFrame& frame) {
  GridRay r;
  const float org[3] = {ray.org.x, ray.org.y, ray.org.z};
  const float dir[3] = {ray.dir.x, ray.dir.y, ray.dir.z};
  for (int a = 0; a < 3; ++a) {
    r.org[a] = float((double(org[a]) - frame.origin[a]) / frame.voxel_size);
    // Scaling the direction by 1/voxel_size keeps t the world-space ray parameter.
    r.inv_dir[a] = float(frame.voxel_size / double(dir[a]));
    r.negative[a] = r.inv_dir[a] < 0.0f;
  }
  r.tmin = ray.tmin, r.tmax = ray.tmax;
  return r;
}

// The first set voxel of the 4x4x4 leaf `leaf` at (x, y, z) along the ray, into `hit` (t, voxel,
// entered face); false when the ray passes through it. Its bytes are the 2x2x2 quarters in
// octant order, their bits the voxels inside.
template <bool kCount>
inline bool leaf_hit(const GridRay& r, std::uint64_t leaf, std::uint32_t x, std::uint32_t y,
                     std::uint32_t z, Cost* cost, VoxelHit& hit) {
  Candidate order[8], inner[8];
  std::uint32_t byte_mask = 0;
  for (std::uint32_t b = 0; b < 8; ++b) byte_mask |= (leaf >> (8 * b) & 0xFF) != 0 ? 1u << b : 0u;
  const int quarters = order_children(r, byte_mask, x, y, z, 2, order);
  for (int q = 0; q < quarters; ++q) {
    const std::uint32_t b = order[q].index;
    if constexpr (kCount) {
      cost->nodes += 1;
      cost->tests += std::uint32_t(std::popcount(std::uint32_t(leaf >> (8 * b) & 0xFF)));
    }
    const std::uint32_t qx = x + (b & 1) * 2, qy = y + (b >> 1 & 1) * 2, qz = z + (b >> 2 & 1) * 2;
    const int voxels =
        order_children(r, std::uint32_t(leaf >> (8 * b) & 0xFF), qx, qy, qz, 1, inner);
    if (voxels == 0) continue;
    const Candidate& v = inner[0];
    hit.t = v.t;
    hit.prim = 0;
    hit.x = qx + (v.index & 1), hit.y = qy + (v.index >> 1 & 1), hit.z = qz + (v.index >> 2 & 1);
    if (v.axis >= 0) hit.face_normal[v.axis] = r.negative[v.axis] ? 1.0f : -1.0f;
    return true;
  }
  return false;
}

}  // namespace kiln::voxel_cast
