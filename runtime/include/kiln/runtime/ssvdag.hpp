// Ray casts and occupancy lookups straight on a symmetry-aware sparse voxel DAG's mapped words.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>

#include "kiln/formats/geometry.hpp"
#include "kiln/formats/ssvdag.hpp"
#include "kiln/runtime/ray.hpp"
#include "kiln/runtime/voxel_grid.hpp"

namespace kiln {

class Blob;

/// A validated view of one SSVDAG (formats/ssvdag.hpp); a RayStructure whose hits are VoxelHits
/// at the finest level, the same hits as the voxel DAG of the same voxels. Creating it parses
/// every interior level once (O(words)): headers with a non-empty child mask and a wide mask
/// inside it, nodes inside their level, one root, every pointer (absolute, relative or wide) at a
/// node start of the next level (or at a leaf from the last interior level), a relative one in a
/// node with a wide pointer, so pointers only go down a level: casts cannot
/// read out of range or loop, whatever the bytes. Throws BlobError otherwise.
class SsvdagView {
 public:
  using HitType = VoxelHit;

  /// `level_first_words`: the first word of each interior level (levels - 2 of them).
  SsvdagView(std::span<const std::uint16_t> words, std::span<const std::uint64_t> leaves,
             const VoxelGridFrame& frame, std::span<const std::uint64_t> level_first_words,
             std::uint32_t root_mirror, const std::string& name = "ssvdag");
  /// The structure named `name` of a blob; throws BlobError when the blob has no structure of
  /// that name or it is not an SSVDAG.
  static SsvdagView from_blob(const Blob& blob, const std::string& name = "ssvdag");

  /// The first voxel along the ray in [tmin, tmax] (front to back, never stepping over a voxel).
  VoxelHit intersect(const Ray& ray) const;
  /// intersect(): the walk is front to back, so the first voxel found is the closest.
  VoxelHit intersect_any(const Ray& ray) const;
  /// Whether any voxel lies along the ray in [tmin, tmax].
  bool occluded(const Ray& ray) const;
  /// intersect(), adding its work to `cost` as VoxelDagView counts it.
  VoxelHit intersect_counting(const Ray& ray, Cost& cost) const;

  bool occupied(std::uint32_t x, std::uint32_t y, std::uint32_t z) const;
  /// Whether the world-space point lies in a set voxel (voxels are half-open boxes).
  bool occupied(const format::Float3& point) const;
  /// The number of set voxels, counted bottom up over the unique nodes (O(words)).
  std::uint64_t count_voxels() const;

  const VoxelGridFrame& frame() const { return frame_; }
  std::uint32_t levels() const { return levels_; }
  std::span<const std::uint16_t> words() const { return words_; }
  std::span<const std::uint64_t> leaves() const { return leaves_; }

 private:
  template <bool kCount>
  VoxelHit cast(const Ray& ray, Cost* cost) const;
  // The word (interior) or leaf index that stored child `stored` of the node at `word`, on
  // level `level`, points at, and the pointer's mirror bits.
  std::uint64_t child(std::uint64_t word, std::uint32_t level, std::uint32_t stored,
                      std::uint32_t& mirror) const;

  std::span<const std::uint16_t> words_;
  std::span<const std::uint64_t> leaves_;
  VoxelGridFrame frame_;
  std::uint32_t levels_ = 0;
  std::uint32_t root_mirror_ = 0;
  std::array<std::uint64_t, 32> first_{};  // interior levels' first words, then words.size()
};

}  // namespace kiln
