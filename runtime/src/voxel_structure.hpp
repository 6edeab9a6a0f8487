// The StructureView of a voxel structure: ray casting (40-byte VoxelHitRecords; the attached
// normal as the surface normal, else the entered face or contour plane) and occupancy, over any
// concrete view V that is a RayStructure with HitType VoxelHit and has occupied(Float3). The
// concrete view's calls stay direct: the one virtual call is the capability's, per query or per
// batch.
#pragma once

#include <concepts>
#include <cstddef>
#include <cstring>
#include <span>
#include <utility>

#include "kiln/formats/geometry.hpp"
#include "kiln/runtime/capabilities.hpp"
#include "kiln/runtime/parallel.hpp"
#include "kiln/runtime/ray_structure.hpp"

namespace kiln {

/// The normal to shade a voxel hit with: the attached normal when the blob stores one (the
/// mesh's own normal, what Laine & Karras shade with: a cube face or a contour plane alone makes
/// blocky, speckled shading), else the entered face or the contour's plane.
inline format::Float3 voxel_normal(const VoxelHit& h) {
  if (h.normal[0] != 0 || h.normal[1] != 0 || h.normal[2] != 0)
    return {h.normal[0], h.normal[1], h.normal[2]};
  return {h.face_normal[0], h.face_normal[1], h.face_normal[2]};
}

/// A voxel structure's view seen through the capabilities: RayQueries and OccupancyQueries.
template <RayStructure V>
requires std::same_as<typename V::HitType, VoxelHit>
class VoxelStructure final : public StructureView, public RayQueries, public OccupancyQueries {
 public:
  explicit VoxelStructure(V view) : view_(std::move(view)) {}

  const RayQueries* rays() const override { return this; }
  const OccupancyQueries* occupancy() const override { return this; }

  std::size_t record_size() const override { return sizeof(VoxelHitRecord); }
  void trace_records(std::span<const Ray> rays, std::span<std::byte> records, bool any_hit,
                     unsigned threads) const override {
    std::byte* out = records.data();
    parallel_for_batched(rays.size(), kRaysPerTask, threads, [&](std::size_t i) {
      const VoxelHitRecord record =
          to_record(any_hit ? view_.intersect_any(rays[i]) : view_.intersect(rays[i]));
      std::memcpy(out + i * sizeof(VoxelHitRecord), &record, sizeof(VoxelHitRecord));
    });
  }
  Hit closest(const Ray& ray) const override { return view_.intersect(ray); }
  bool closest_voxel(const Ray& ray, VoxelHit& out) const override {
    out = view_.intersect(ray);
    return true;
  }
  bool has_colors() const override {
    if constexpr (requires(const V& v) { v.has_colors(); })
      return view_.has_colors();
    else
      return false;
  }
  bool voxel_frame(VoxelGridFrame& out) const override {
    out = view_.frame();
    return true;
  }
  SurfaceHit intersect_counting(const Ray& ray, Cost& cost) const override {
    const VoxelHit h = view_.intersect_counting(ray, cost);
    SurfaceHit surface{h};
    if (h.hit()) surface.normal = voxel_normal(h);
    return surface;
  }

  bool occupied(const format::Float3& point) const override { return view_.occupied(point); }

 private:
  V view_;
};

}  // namespace kiln
