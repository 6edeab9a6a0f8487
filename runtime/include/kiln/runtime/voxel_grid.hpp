// Where a voxel structure's cubic grid sits in world space: the frame every voxel structure
// carries in its manifest entry.
#pragma once

#include <cstdint>

namespace kiln {

/// Voxel (x, y, z) spans origin + [x, x+1] * voxel_size on each axis; `resolution` voxels per
/// side, a power of two (format::is_valid_voxel_resolution).
struct VoxelGridFrame {
  double origin[3] = {0, 0, 0};
  double voxel_size = 1;
  std::uint32_t resolution = 0;
};

}  // namespace kiln
