// Options shared by the voxel structures, declared once so that their global flags agree.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>

#include "kiln/compiler/structure_builder.hpp"
#include "kiln/formats/voxel_grid.hpp"

namespace kiln {

/// `resolution` (global flag --resolution): the voxel grid's side at the finest level, a power
/// of two in 8..max (the kind's limit: kVoxelInCoreMaxResolution = 16384 for the kinds that
/// voxelize the whole grid at once); default 512.
StructureOption voxel_resolution_option(std::uint32_t max = format::kVoxelInCoreMaxResolution);

/// Parses a memory size: a whole number of bytes with an optional suffix K, M, G or T (powers of
/// 1024, case-insensitive, an optional trailing B or iB). Throws std::invalid_argument with a
/// one-line reason for anything else, zero, or a size past 2^64.
std::uint64_t parse_memory_size(std::string_view text);

/// `memory-budget` (global flag --memory-budget SIZE, e.g. 8G): bytes a voxel build may hold at
/// once; "auto" (the default) is default_memory_budget(). Never changes the blob. Canonical text:
/// the byte count, or "auto".
StructureOption memory_budget_option();

/// The out-of-core DAG build's progress line on a terminal ("dag: cube 12/512, 31 % of voxels,
/// ETA 1m20s"); empty (no progress) when standard error is not a terminal.
std::function<void(std::uint64_t, std::uint64_t, double)> terminal_progress();

/// The byte count of a canonical memory-budget value ("auto": default_memory_budget()).
std::uint64_t memory_budget_bytes(const std::string& canonical);

}  // namespace kiln
