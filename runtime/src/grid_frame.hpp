// The voxel grid frame both voxel structures (DAG, ESVO) carry in their manifest entries, and
// the checks both views make of it.
#pragma once

#include <cmath>
#include <string>

#include "kiln/formats/voxel_dag.hpp"
#include "kiln/runtime/voxel_dag.hpp"

namespace kiln {

// From a schema::VoxelDagDesc or schema::EsvoDesc: the same five fields.
template <class Desc>
VoxelGridFrame grid_frame_of(const Desc& d) {
  VoxelGridFrame frame;
  frame.origin[0] = d.origin_x(), frame.origin[1] = d.origin_y(), frame.origin[2] = d.origin_z();
  frame.voxel_size = d.voxel_size();
  frame.resolution = d.resolution();
  return frame;
}

// Empty when the frame is usable: a power-of-two resolution in range, a finite positive voxel.
inline std::string grid_frame_problem(const VoxelGridFrame& frame) {
  if (!format::is_valid_dag_resolution(frame.resolution))
    return "resolution " + std::to_string(frame.resolution) + " is not a power of two in range";
  if (!(frame.voxel_size > 0) || !std::isfinite(frame.voxel_size)) return "bad voxel size";
  return {};
}

}  // namespace kiln
