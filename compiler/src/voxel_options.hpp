// Options shared by the voxel structures, declared once so that their global flags agree.
#pragma once

#include "kiln/compiler/structure_builder.hpp"
#include "kiln/formats/voxel_grid.hpp"

namespace kiln {

/// `resolution` (global flag --resolution): the voxel grid's side at the finest level, a power
/// of two in 8..max (the kind's limit: kVoxelInCoreMaxResolution = 16384 for the kinds that
/// voxelize the whole grid at once); default 512.
StructureOption voxel_resolution_option(std::uint32_t max = format::kVoxelInCoreMaxResolution);

}  // namespace kiln
