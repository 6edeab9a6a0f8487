// Front-to-back ray casting on the SSVDAG: the voxel DAG's walk (voxel_cast_steps.hpp), with
// each stacked cell carrying the mirror accumulated along its path. A node stored under mirror m
// has its actual octant o at stored octant o ^ m, and its child pointer's mirror composes with m
// (mirrors along the axes commute and undo themselves: XOR); a leaf is mirrored before the walk
// through its bits. The cells visited and their order are the DAG's, so are the hits.
#include "kiln/runtime/ssvdag.hpp"
#include "voxel_cast_steps.hpp"

namespace kiln {

namespace {

using namespace voxel_cast;

struct Cell {
  std::uint64_t word;  // interior: word of the node; leaf level: leaf index
  std::uint32_t level, x, y, z, mirror;
};

}  // namespace

template <bool kCount>
VoxelHit SsvdagView::cast(const Ray& ray, Cost* cost) const {
  const GridRay r = grid_ray(ray, frame_);
  VoxelHit hit;
  float t_root;
  int axis_root;
  if (!enter(r, 0, 0, 0, frame_.resolution, t_root, axis_root)) return hit;
  const std::uint32_t leaf_level = levels_ - 2;
  // As the DAG's: at most 7 cells waiting per level, one expanded.
  Cell stack[8 * 18];  // 17 levels at format::kVoxelMaxResolution
  std::uint32_t top = 0;
  stack[top++] = {0, 0, 0, 0, 0, root_mirror_};
  Candidate order[8];
  while (top > 0) {
    const Cell c = stack[--top];
    if constexpr (kCount) cost->nodes += 1;
    if (c.level >= leaf_level) {
      const std::uint64_t leaf = format::ssvdag_mirror_leaf(leaves_[c.word], c.mirror);
      if (!leaf_hit<kCount>(r, leaf, c.x, c.y, c.z, cost, hit)) continue;
      hit.level = levels_;
      return hit;
    }
    const std::uint32_t half = frame_.resolution >> (c.level + 1);
    const std::uint32_t mask = format::ssvdag_mirror_mask(words_[c.word] & 0xFFu, c.mirror);
    const int count = order_children(r, mask, c.x, c.y, c.z, half, order);
    for (int i = count; i-- > 0;) {
      const std::uint32_t octant = order[i].index;
      std::uint32_t mirror;
      const std::uint64_t child_word = child(c.word, c.level, octant ^ c.mirror, mirror);
      stack[top++] = {child_word,
                      c.level + 1,
                      c.x + (octant & 1) * half,
                      c.y + (octant >> 1 & 1) * half,
                      c.z + (octant >> 2 & 1) * half,
                      c.mirror ^ mirror};
    }
  }
  return hit;
}

VoxelHit SsvdagView::intersect(const Ray& ray) const {
  return cast<false>(ray, nullptr);
}

VoxelHit SsvdagView::intersect_any(const Ray& ray) const {
  return cast<false>(ray, nullptr);
}

VoxelHit SsvdagView::intersect_counting(const Ray& ray, Cost& cost) const {
  return cast<true>(ray, &cost);
}

bool SsvdagView::occluded(const Ray& ray) const {
  return cast<false>(ray, nullptr).hit();
}

}  // namespace kiln
