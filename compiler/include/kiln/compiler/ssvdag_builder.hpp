// Symmetry-aware sparse voxel DAG construction (Villanueva, Marton, Gobbetti 2016) from the same
// 4x4x4 leaves as the voxel DAG, producing the words and leaves of formats/ssvdag.hpp.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "kiln/compiler/voxel_dag_builder.hpp"
#include "kiln/compiler/voxelizer.hpp"
#include "kiln/formats/ssvdag.hpp"

namespace kiln {

/// One level (root = 0, the last = the 4x4x4 leaves): node counts of the plain octree, of the
/// DAG (identical subtrees merged) and of the SSVDAG (subtrees equal up to mirroring merged).
struct SsvdagLevelStats {
  std::uint64_t svo_nodes = 0, dag_nodes = 0, ssvdag_nodes = 0, bytes = 0, first_word = 0;
  std::uint64_t wide_pointers = 0, narrow_pointers = 0;  // pointers from this level's nodes
  std::uint64_t relative_pointers = 0;                   // of the narrow ones, relative
};

/// How far the layout lets each kind of pointer reach (formats/ssvdag.hpp's reaches by default).
/// Any lower values give a valid SSVDAG too, with more wide pointers; tests lower them so that
/// small SSVDAGs take every kind of pointer.
struct SsvdagPointerReach {
  std::uint32_t leaf = format::kSsvdagNarrowOffsets;        // narrow into the leaves, <= 2^13
  std::uint32_t absolute = format::kSsvdagAbsoluteOffsets;  // narrow absolute, <= 2^12
  std::int64_t relative = format::kSsvdagRelativeReach;     // narrow relative, <= 2^11
};

/// The SSVDAG as laid out in its two sections, with the statistics kiln dump prints.
struct FlatSsvdag {
  std::uint32_t levels = 0;           // log2(resolution)
  std::vector<std::uint16_t> words;   // SSVR: interior levels
  std::vector<std::uint64_t> leaves;  // SSVL: 4x4x4 leaf masks
  std::uint32_t root_mirror = 0;
  std::vector<SsvdagLevelStats> level_stats;  // levels - 1 entries: 0 .. levels - 2 (leaves)
  std::uint64_t voxel_count = 0, svo_bytes = 0, dag_bytes = 0, ssvdag_bytes = 0;
  std::uint64_t symmetry_merges = 0;  // sum over levels of dag_nodes - ssvdag_nodes
};

/// Bottom up over the voxel DAG's unique nodes: every node is brought to its canonical form, the
/// least of its eight mirror images, and nodes with equal canonical forms merge; a pointer stores
/// the mirror that turns the canonical node into the subtree it stands for. Then each level is
/// laid out, its most referenced nodes first (as many as absolute narrow pointers reach), the
/// others in id order, with narrow (absolute or relative) or wide pointers. Canonical forms are
/// computed on `threads` threads, ids assigned in the DAG's id order (first occurrence in Morton
/// order) on one, so the output depends on the voxels alone. Touching only unique nodes (far
/// fewer than the octree's), it scales with the DAG, not with the voxels.
FlatSsvdag build_ssvdag(const FlatVoxelDag& dag, unsigned threads,
                        const SsvdagPointerReach& reach = {});
/// The same from the voxels: build_voxel_dag, then the above. `leaves` as build_voxel_dag takes
/// them (keys ascending, masks non-zero, non-empty).
FlatSsvdag build_ssvdag(const VoxelLeaves& leaves, std::uint32_t resolution, unsigned threads,
                        const SsvdagPointerReach& reach = {});
FlatSsvdag build_ssvdag(std::span<const std::uint64_t> codes, std::uint32_t resolution,
                        unsigned threads, const SsvdagPointerReach& reach = {});

/// The interior levels' first words, as SsvdagView takes them.
std::vector<std::uint64_t> ssvdag_level_first_words(const FlatSsvdag& ssvdag);

/// Every voxel of the SSVDAG as sorted Morton codes, applying the mirrors (for tests and tools).
std::vector<std::uint64_t> expand_ssvdag(const FlatSsvdag& ssvdag);

}  // namespace kiln
