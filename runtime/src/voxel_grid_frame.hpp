// The voxel grid frame as the voxel structures' manifest entries record it, and the checks every
// voxel view makes of it.
#pragma once

#include <cmath>
#include <limits>
#include <string>

#include "kiln/formats/voxel_grid.hpp"
#include "kiln/runtime/voxel_grid.hpp"

namespace kiln {

// From a description table with the five grid fields (origin_x/y/z, voxel_size, resolution).
template <class Desc>
VoxelGridFrame grid_frame_of(const Desc& d) {
  VoxelGridFrame frame;
  frame.origin[0] = d.origin_x(), frame.origin[1] = d.origin_y(), frame.origin[2] = d.origin_z();
  frame.voxel_size = d.voxel_size();
  frame.resolution = d.resolution();
  return frame;
}

// Empty when the frame is usable: a power-of-two resolution in range, a finite positive voxel,
// and a grid whose corners are finite floats (queries and casts work in float world space).
// `max_resolution`: the kind's own limit (its casts' stacks are sized for it).
inline std::string grid_frame_problem(
    const VoxelGridFrame& frame, std::uint32_t max_resolution = format::kVoxelInCoreMaxResolution) {
  if (!format::is_valid_voxel_resolution(frame.resolution, max_resolution))
    return "resolution " + std::to_string(frame.resolution) + " is not a power of two in range";
  if (!(frame.voxel_size > 0) || !std::isfinite(frame.voxel_size)) return "bad voxel size";
  const double extent = frame.voxel_size * frame.resolution;
  for (const double origin : frame.origin)
    if (!(std::fabs(origin) <= std::numeric_limits<float>::max()) ||
        !(std::fabs(origin + extent) <= std::numeric_limits<float>::max()))
      return "grid out of float range";
  return {};
}

}  // namespace kiln
