// Ray casts and occupancy lookups straight on a sparse voxel DAG's mapped words.
#pragma once

#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "kiln/formats/voxel_dag.hpp"
#include "kiln/runtime/ray.hpp"

namespace kiln {

class Blob;

// The voxel-hit record of `kiln trace` on a voxel structure (docs/FORMAT.md §13), 40 bytes.
struct VoxelHit {
  float t = std::numeric_limits<float>::infinity();  // +inf on a miss
  std::uint32_t x = kNoHit, y = kNoHit, z = kNoHit;  // the voxel; 0xFFFFFFFF on a miss
  float face_normal[3] = {0, 0,
                          0};   // the entered face's outward normal; 0 if the ray starts inside
  float normal[3] = {0, 0, 0};  // the voxel's attached normal; 0 when the blob has none
  bool hit() const { return x != kNoHit; }
};
static_assert(sizeof(VoxelHit) == 40);

// Where the DAG sits in world space: voxel (x, y, z) spans origin + [x, x+1] * voxel_size.
struct VoxelGridFrame {
  double origin[3] = {0, 0, 0};
  double voxel_size = 1;
  std::uint32_t resolution = 0;
};

// A validated view of one voxel DAG. Creating it parses every level's nodes once (O(words)):
// child masks of at most 8 bits, every pointer at a node start of the next level (or at a leaf
// mask from the last interior level), levels contiguous as the manifest says; so casts cannot
// read out of range or loop, whatever the bytes. Throws BlobError otherwise.
class VoxelDagView {
 public:
  VoxelDagView(std::span<const std::uint32_t> words, const VoxelGridFrame& frame,
               std::span<const std::uint64_t> level_first_words, std::uint64_t leaf_first_word,
               std::span<const std::uint64_t> codes, std::span<const std::uint32_t> normals,
               const std::string& name = "dag");
  static VoxelDagView from_blob(const Blob& blob, const std::string& name = "dag");

  // The first voxel along the ray in [tmin, tmax] (front to back, never stepping over a voxel).
  VoxelHit intersect(const Ray& ray) const;
  // Whether any voxel lies along the ray in [tmin, tmax].
  bool occluded(const Ray& ray) const;
  // intersect() without the attached normal (stays 0).
  VoxelHit intersect_any(const Ray& ray) const;

  // The work of one intersect() (for heatmaps and statistics): nodes = interior nodes and 4x4x4
  // leaves taken off the stack plus leaf quarters (2x2x2) opened; voxels = voxel boxes
  // slab-tested inside the opened quarters.
  struct Cost {
    std::uint32_t nodes = 0, voxels = 0;
  };
  VoxelHit intersect_counting(const Ray& ray, Cost& cost) const;
  bool occupied(std::uint32_t x, std::uint32_t y, std::uint32_t z) const;
  // Whether the world-space point lies in a set voxel (voxels are half-open boxes).
  bool occupied(const format::Float3& point) const;
  // The attached normal of a set voxel; false when the blob has no normals or the voxel is empty.
  bool attached_normal(std::uint32_t x, std::uint32_t y, std::uint32_t z, float n[3]) const;

  const VoxelGridFrame& frame() const { return frame_; }
  std::uint32_t levels() const { return levels_; }
  std::span<const std::uint32_t> words() const { return words_; }

 private:
  // kCount: tally into *cost; a compile-time flag so the plain casts pay nothing for it.
  template <bool kAnyHit, bool kCount>
  VoxelHit cast(const Ray& ray, Cost* cost) const;

  std::span<const std::uint32_t> words_;
  VoxelGridFrame frame_;
  std::uint32_t levels_ = 0;
  std::span<const std::uint64_t> codes_;
  std::span<const std::uint32_t> normals_;
};

// Casts many rays on up to `threads` threads (0 = all cores).
void trace_rays(const VoxelDagView& dag, std::span<const Ray> rays, std::span<VoxelHit> hits,
                bool any_hit, unsigned threads);

}  // namespace kiln
