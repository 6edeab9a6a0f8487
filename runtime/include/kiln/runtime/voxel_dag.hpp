// Ray casts and occupancy lookups straight on a sparse voxel DAG's mapped words.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "kiln/formats/geometry.hpp"
#include "kiln/formats/voxel_dag.hpp"
#include "kiln/runtime/ray.hpp"
#include "kiln/runtime/voxel_grid.hpp"

namespace kiln {

class Blob;

/// A validated view of one voxel DAG; a RayStructure (kiln/runtime/ray_structure.hpp) whose hits
/// are VoxelHits at the finest level. Creating it parses every level's nodes once (O(words)):
/// child masks of at most 8 bits, every pointer at a node start of the next level (or at a leaf
/// mask from the last interior level), levels contiguous as the manifest says; so casts cannot
/// read out of range or loop, whatever the bytes. Throws BlobError otherwise.
class VoxelDagView {
 public:
  using HitType = VoxelHit;

  VoxelDagView(std::span<const std::uint32_t> words, const VoxelGridFrame& frame,
               std::span<const std::uint64_t> level_first_words, std::uint64_t leaf_first_word,
               std::span<const std::uint64_t> codes, std::span<const std::uint32_t> normals,
               const std::string& name = "dag");
  /// The structure named `name` of a blob; throws BlobError when the blob has no structure of
  /// that name or it is not a voxel DAG.
  static VoxelDagView from_blob(const Blob& blob, const std::string& name = "dag");

  /// The first voxel along the ray in [tmin, tmax] (front to back, never stepping over a voxel),
  /// with its attached normal.
  VoxelHit intersect(const Ray& ray) const;
  /// intersect() without the attached normal (stays 0): the walk is front to back, so the first
  /// voxel found is the closest either way.
  VoxelHit intersect_any(const Ray& ray) const;
  /// Whether any voxel lies along the ray in [tmin, tmax].
  bool occluded(const Ray& ray) const;
  /// intersect(), adding its work to `cost`: nodes = interior nodes and 4x4x4 leaves taken off
  /// the stack plus leaf quarters (2x2x2) opened; tests = voxel boxes slab-tested inside the
  /// opened quarters.
  VoxelHit intersect_counting(const Ray& ray, Cost& cost) const;

  bool occupied(std::uint32_t x, std::uint32_t y, std::uint32_t z) const;
  /// Whether the world-space point lies in a set voxel (voxels are half-open boxes).
  bool occupied(const format::Float3& point) const;
  /// The attached normal of a set voxel; false when the blob has no normals or the voxel is
  /// empty.
  bool attached_normal(std::uint32_t x, std::uint32_t y, std::uint32_t z, float n[3]) const;

  const VoxelGridFrame& frame() const { return frame_; }
  std::uint32_t levels() const { return levels_; }
  std::span<const std::uint32_t> words() const { return words_; }
  /// The attachment's Morton codes (ascending) and normals; empty without attachments.
  std::span<const std::uint64_t> codes() const { return codes_; }

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

}  // namespace kiln
