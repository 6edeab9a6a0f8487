// Options shared by the voxel structures, declared once so that their global flags agree.
#pragma once

#include "kiln/compiler/structure_builder.hpp"

namespace kiln {

/// `resolution` (global flag --resolution): the voxel grid's side at the finest level, a power
/// of two in 8..16384; default 512.
StructureOption voxel_resolution_option();

}  // namespace kiln
