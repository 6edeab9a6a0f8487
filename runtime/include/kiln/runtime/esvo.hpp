// Ray casts and occupancy lookups on an Efficient Sparse Voxel Octree's mapped words, following
// Laine & Karras 2010: the octree lives in [1,2]^3, mirrored so the ray runs towards -x, -y, -z,
// with a stack of (parent, t_max) per level and the float-exponent trick to find the level on POP.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "kiln/formats/esvo.hpp"
#include "kiln/formats/geometry.hpp"
#include "kiln/runtime/ray.hpp"
#include "kiln/runtime/voxel_grid.hpp"

namespace kiln {

class Blob;

/// Level-of-detail stop: a voxel counts as hit once it is smaller than the ray's cone footprint
/// at the voxel's exit, footprint(t) = coef * t + bias in world units. {0, 0}: never.
struct EsvoLod {
  float coef = 0, bias = 0;
};

/// A validated view of one ESVO; a RayStructure (kiln/runtime/ray_structure.hpp). A hit is the
/// VoxelHit of the leaf region entered: t; the finest-grid voxel holding the hit point; the
/// normal of the surface entered (the contour's plane when its slab set t, else the cube's
/// face); the attached normal and colour; the level of the leaf.
/// Creating it walks every descriptor once (O(descriptors)): each pointer lands inside the words
/// on an even, forward index; the tree is no deeper than `levels`; masks agree (non-leaf and
/// contour bits only on valid children); runs, far pointers, pages, blocks and attachment
/// indices stay in range. So a cast cannot read out of range or loop.
class EsvoView {
 public:
  using HitType = VoxelHit;

  EsvoView(std::span<const std::uint32_t> words, std::span<const std::uint32_t> pages,
           std::span<const format::EsvoBlockInfo> blocks, std::span<const std::uint32_t> normals,
           std::span<const std::uint32_t> colors, const VoxelGridFrame& frame,
           const std::string& name = "esvo");
  /// The structure named `name` of a blob; throws BlobError when the blob has no structure of
  /// that name or it is not an ESVO.
  static EsvoView from_blob(const Blob& blob, const std::string& name = "esvo");

  /// The first leaf region (cube cut by its own and its ancestors' contours) along the ray, with
  /// its attachments; with `lod`, the first voxel smaller than the ray's footprint.
  VoxelHit intersect(const Ray& ray) const;
  VoxelHit intersect(const Ray& ray, const EsvoLod& lod) const;
  /// intersect() without the attachment lookup (normal and colour stay 0): the walk is front to
  /// back, so the first leaf found is the closest either way.
  VoxelHit intersect_any(const Ray& ray) const;
  VoxelHit intersect_any(const Ray& ray, const EsvoLod& lod) const;
  /// Whether any leaf region lies along the ray.
  bool occluded(const Ray& ray) const;
  bool occluded(const Ray& ray, const EsvoLod& lod) const;
  /// intersect(), adding its work to `cost`: nodes = descriptors fetched (the root, each PUSH
  /// and each POP); tests = child slots examined (one per iteration of the kernel: its valid
  /// bit, and its contour when it has one).
  VoxelHit intersect_counting(const Ray& ray, Cost& cost) const;
  VoxelHit intersect_counting(const Ray& ray, Cost& cost, const EsvoLod& lod) const;
  /// Whether the world-space point lies in a leaf's region.
  bool occupied(const format::Float3& point) const;

  const VoxelGridFrame& frame() const { return frame_; }
  std::uint32_t levels() const { return levels_; }
  /// Whether hits carry a stored colour (the input had vertex or material colours).
  bool has_colors() const { return !colors_.empty(); }
  std::span<const std::uint32_t> words() const { return words_; }
  /// What the validation walk found: reachable descriptors, their children (voxels), leaves
  /// among them, and contours.
  struct Counts {
    std::uint64_t descriptors = 0, voxels = 0, leaves = 0, contours = 0;
  };
  const Counts& counts() const { return counts_; }

 private:
  // kCount: tally into *cost; a compile-time flag so the plain casts pay nothing for it.
  template <bool kAnyHit, bool kCount>
  VoxelHit cast(const Ray& ray, const EsvoLod& lod, Cost* cost) const;
  // The block holding word `w` (its page header names the block the page starts in).
  std::size_t block_of(std::uint64_t w) const;
  std::uint64_t attachment_index(std::uint64_t descriptor_word, std::uint32_t w0, std::uint32_t w1,
                                 std::uint32_t octant) const;
  // The descriptor walk behind the constructor: fills counts_, throws on bad words.
  void check_descriptors(const std::string& name);

  std::span<const std::uint32_t> words_, pages_;
  std::span<const format::EsvoBlockInfo> blocks_;
  std::span<const std::uint32_t> normals_, colors_;
  VoxelGridFrame frame_;
  std::uint32_t levels_ = 0;
  Counts counts_;
};

}  // namespace kiln
