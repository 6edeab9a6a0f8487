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
#include "voxel_cast_steps.hpp"

namespace kiln {

namespace {

using namespace voxel_cast;

struct Cell {
  std::uint32_t word, level, x, y, z;
};

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
  Cell stack[8 * 18];  // 17 levels at format::kVoxelMaxResolution
  static_assert(format::kVoxelMaxResolution <= (1u << 17));
  std::uint32_t top = 0;
  stack[top++] = {0, 0, 0, 0, 0};
  Candidate order[8];
  while (top > 0) {
    const Cell c = stack[--top];
    if constexpr (kCount) cost->nodes += 1;
    if (c.level >= leaf_level) {
      const std::uint64_t leaf = words_[c.word] | std::uint64_t(words_[c.word + 1]) << 32;
      if (!leaf_hit<kCount>(r, leaf, c.x, c.y, c.z, cost, hit)) continue;
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
