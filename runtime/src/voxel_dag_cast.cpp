// Front-to-back ray casting on the DAG in grid space (voxel = unit cube): at each node the
// present children the ray enters are slab-tested on their exact integer boxes and pushed
// farthest first, so the nearest is expanded next; children of a node are disjoint boxes, so
// entry order is hit order and the first voxel reached is the closest. Every cell the ray
// touches is tested, so no voxel is stepped over. Leaves (4x4x4 masks) are walked the same way
// through their eight 2x2x2 bytes, then their bits.
#include <algorithm>
#include <bit>
#include <cmath>

#include "kiln/runtime/voxel_dag.hpp"

namespace kiln {

namespace {

struct GridRay {
  float org[3], inv_dir[3];
  float tmin, tmax;
  bool negative[3];
};

// Entry distance of the ray into the box [lo, lo + size]^3 within [tmin, tmax] and the axis
// whose face it enters through (-1: it starts inside); false when it misses.
bool enter(const GridRay& r, std::uint32_t x, std::uint32_t y, std::uint32_t z, std::uint32_t size,
           float& t_enter, int& axis) {
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

struct Cell {
  std::uint32_t word, level, x, y, z;
};

struct Candidate {
  float t;
  int axis;
  std::uint32_t index;  // octant, or bit
};

// The present children (bits of `mask`) the ray enters, nearest first.
int order_children(const GridRay& r, std::uint32_t mask, std::uint32_t x, std::uint32_t y,
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
GridRay grid_ray(const Ray& ray, const VoxelGridFrame& frame) {
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

// The first set voxel of the 4x4x4 leaf `leaf` at cell `c` along the ray, into `hit` (t, voxel,
// entered face); false when the ray passes through it. Its bytes are the 2x2x2 quarters in
// octant order, their bits the voxels inside.
template <bool kCount>
bool leaf_hit(const GridRay& r, std::uint64_t leaf, const Cell& c, Cost* cost, VoxelHit& hit) {
  Candidate order[8], inner[8];
  std::uint32_t byte_mask = 0;
  for (std::uint32_t b = 0; b < 8; ++b) byte_mask |= (leaf >> (8 * b) & 0xFF) != 0 ? 1u << b : 0u;
  const int quarters = order_children(r, byte_mask, c.x, c.y, c.z, 2, order);
  for (int q = 0; q < quarters; ++q) {
    const std::uint32_t b = order[q].index;
    if constexpr (kCount) {
      cost->nodes += 1;
      cost->tests += std::uint32_t(std::popcount(std::uint32_t(leaf >> (8 * b) & 0xFF)));
    }
    const std::uint32_t qx = c.x + (b & 1) * 2, qy = c.y + (b >> 1 & 1) * 2,
                        qz = c.z + (b >> 2 & 1) * 2;
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

}  // namespace

template <bool kAnyHit, bool kCount>
VoxelHit VoxelDagView::cast(const Ray& ray, Cost* cost) const {
  const GridRay r = grid_ray(ray, frame_);
  VoxelHit hit;
  float t_root;
  int axis_root;
  if (!enter(r, 0, 0, 0, frame_.resolution, t_root, axis_root)) return hit;
  const std::uint32_t leaf_level = levels_ - 2;
  // A node pushes at most its eight children (a line meets four octants; eight when it grazes
  // the centre), and only the last pushed is expanded: at most 7 waiting per level.
  Cell stack[8 * 16];
  std::uint32_t top = 0;
  stack[top++] = {0, 0, 0, 0, 0};
  Candidate order[8];
  while (top > 0) {
    const Cell c = stack[--top];
    if constexpr (kCount) cost->nodes += 1;
    if (c.level >= leaf_level) {
      const std::uint64_t leaf = words_[c.word] | std::uint64_t(words_[c.word + 1]) << 32;
      if (!leaf_hit<kCount>(r, leaf, c, cost, hit)) continue;
      hit.level = levels_;
      if constexpr (!kAnyHit) attached_normal(hit.x, hit.y, hit.z, hit.normal);
      return hit;
    }
    const std::uint32_t half = frame_.resolution >> (c.level + 1);
    const std::uint32_t mask = words_[c.word];
    const int count = order_children(r, mask, c.x, c.y, c.z, half, order);
    for (int i = count; i-- > 0;) {
      const std::uint32_t octant = order[i].index;
      const std::uint32_t child = words_[c.word + 1 + std::popcount(mask & ((1u << octant) - 1))];
      stack[top++] = {child, c.level + 1, c.x + (octant & 1) * half, c.y + (octant >> 1 & 1) * half,
                      c.z + (octant >> 2 & 1) * half};
    }
  }
  return hit;
}

VoxelHit VoxelDagView::intersect(const Ray& ray) const {
  return cast<false, false>(ray, nullptr);
}

VoxelHit VoxelDagView::intersect_counting(const Ray& ray, Cost& cost) const {
  return cast<false, true>(ray, &cost);
}

bool VoxelDagView::occluded(const Ray& ray) const {
  return cast<true, false>(ray, nullptr).hit();
}

VoxelHit VoxelDagView::intersect_any(const Ray& ray) const {
  return cast<true, false>(ray, nullptr);
}

}  // namespace kiln
