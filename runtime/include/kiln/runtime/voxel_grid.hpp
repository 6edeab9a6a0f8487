// Where a voxel structure's cubic grid sits in world space: the frame every voxel structure
// carries in its manifest entry.
#pragma once

#include <array>
#include <cstdint>
#include <optional>

#include "kiln/formats/geometry.hpp"

namespace kiln {

/// Voxel (x, y, z) spans origin + [x, x+1] * voxel_size on each axis; `resolution` voxels per
/// side, a power of two (format::is_valid_voxel_resolution).
struct VoxelGridFrame {
  double origin[3] = {0, 0, 0};
  double voxel_size = 1;
  std::uint32_t resolution = 0;

  /// The voxel holding a world-space point; nothing outside the grid (or for NaN).
  std::optional<std::array<std::uint32_t, 3>> cell_of(const format::Float3& point) const {
    const double p[3] = {point.x, point.y, point.z};
    std::array<std::uint32_t, 3> cell{};
    for (int a = 0; a < 3; ++a) {
      const double g = (p[a] - origin[a]) / voxel_size;
      if (!(g >= 0 && g < double(resolution))) return std::nullopt;
      cell[a] = std::uint32_t(g);
    }
    return cell;
  }
};

}  // namespace kiln
