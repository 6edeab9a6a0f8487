// The one ray contract: rays and hits laid out as the RAYS and HITS files (docs/FORMAT.md), the
// voxel hit that extends the hit, and the traversal cost every ray structure counts.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>

#include "kiln/formats/geometry.hpp"

namespace kiln {

struct Ray {
  format::Float3 org;
  float tmin;
  format::Float3 dir;
  float tmax;
};
static_assert(sizeof(Ray) == 32);

inline constexpr std::uint32_t kNoHit = 0xFFFFFFFFu;

// Rays per task of the batch trace_rays.
inline constexpr std::size_t kRaysPerTask = 4096;

/// A ray's hit: the HITS record of a triangle structure (16 bytes). A miss has prim == kNoHit
/// and t == +inf.
struct Hit {
  float t = std::numeric_limits<float>::infinity();
  std::uint32_t prim = kNoHit;  // original primitive (triangle) id; 0 for a voxel hit
  float u = 0, v = 0;           // barycentric weights of the triangle's second and third corners
  bool hit() const { return prim != kNoHit; }
};
static_assert(sizeof(Hit) == 16);

/// A voxel structure's hit: the Hit (prim 0 when something was hit, u = v = 0) extended with the
/// voxel, the normal of the surface entered and the voxel's attachments.
struct VoxelHit : Hit {
  std::uint32_t x = kNoHit, y = kNoHit, z = kNoHit;  // finest-grid voxel; kNoHit on a miss
  float face_normal[3] = {0, 0, 0};  // entered face (or contour plane); 0 if the ray starts inside
  float normal[3] = {0, 0, 0};       // attached normal; 0 when the blob has none
  std::uint32_t level = 0;  // level of the leaf hit (the finest level for fixed-depth trees)
  std::uint32_t color = 0;  // RGBA8 attachment (r in the low byte); 0 without colours
};

/// The voxel-hit record of `kiln trace` on a voxel structure (docs/FORMAT.md), 40 bytes.
struct VoxelHitRecord {
  float t;
  std::uint32_t x, y, z;
  float face_normal[3];
  float normal[3];
};
static_assert(sizeof(VoxelHitRecord) == 40);

inline VoxelHitRecord to_record(const VoxelHit& h) {
  return {h.t,
          h.x,
          h.y,
          h.z,
          {h.face_normal[0], h.face_normal[1], h.face_normal[2]},
          {h.normal[0], h.normal[1], h.normal[2]}};
}

/// The work of one query, for heatmaps and statistics: node visits, and primitive tests
/// (triangles; voxel tests for voxel structures).
struct Cost {
  std::uint32_t nodes = 0, tests = 0;
};

}  // namespace kiln
