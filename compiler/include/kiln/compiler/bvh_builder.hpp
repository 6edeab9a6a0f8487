// BVH builders (binned SAH, full-sweep SAH, SBVH), each emitting its nodes straight into the
// mapped flat layout (formats/bvh.hpp), and the statistics they report.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "kiln/compiler/scene.hpp"
#include "kiln/compiler/uninitialized_allocator.hpp"
#include "kiln/formats/bvh.hpp"
#include "kiln/formats/geometry.hpp"

namespace kiln {

enum class BvhBuilder { kBinned, kSweep, kSpatial };

/// Triangle subdivision before the build (binned and sweep builders only).
enum class BvhPresplit {
  kNone,
  /// Edge volume heuristic (Dammertz & Keller 2008): a triangle whose largest edge volume (the
  /// volume of the box its edge spans) exceeds evh_threshold x the scene box's volume is halved
  /// at that edge, recursively, each piece's box becoming one build reference to the original
  /// triangle (bvh_evh_presplit.hpp).
  kEvh,
};

const char* bvh_builder_name(BvhBuilder builder);

/// The EVH threshold `--bvh-presplit evh` means, as a fraction of the scene box's volume: 2^-14
/// (docs/BENCHMARKS.md, "Edge volume heuristic", says why).
inline constexpr double kEvhDefaultThreshold = 1.0 / 16384;

struct BvhBuildOptions {
  BvhBuilder builder = BvhBuilder::kBinned;
  std::uint32_t bins = 32;          // SAH bins (2-1024): binned, at most (object_bin_count); SBVH
  float traversal_cost = 1.0f;      // SAH cost of visiting a node
  float intersection_cost = 1.0f;   // SAH cost of one triangle test
  std::uint32_t max_leaf_size = 8;  // larger leaves are split even when the SAH disagrees
  // Leaves priced per packet of this many references (at most 8; the wide layouts' 4-triangle
  // packets: `kiln build` sets 4 for widths 4, 8 and 16): a node of at most max_leaf_size
  // references is a leaf unless splitting it saves packet-weighted area (each side's area x its
  // packets below the node's area x its packets), so the binary tree stops where the collapse would
  // pack leaves anyway. Nodes of one packet or less try every cut instead of binning (binned
  // builder). 0: every reference costs its own test (the binary layout).
  std::uint32_t leaf_packet = 0;
  float sbvh_alpha = 1e-5f;           // try spatial splits when child overlap > alpha * root area
  float sbvh_max_duplication = 1.0f;  // at most (1 + this) x triangles references
  unsigned threads = 0;               // never changes the result
  std::uint32_t width = 2;            // stored layout: 2 (binary), 4, 8 or 16 (bvh_collapse.hpp);
                                      // build_bvh ignores it and always returns the binary tree
  bool quantized = false;             // wide layouts: 8-bit child boxes (ignored by build_bvh)
  // Fill FlatBvh::triangles (the binary layout's leaf triangles). The wide layout reads corners
  // from the scene instead, which saves 36 bytes per triangle at the build's peak.
  bool leaf_triangles = true;
  BvhPresplit presplit = BvhPresplit::kNone;
  double evh_threshold = kEvhDefaultThreshold;  // fraction of the scene box's volume
  std::uint32_t evh_max_refs = 8;               // references per triangle at most (>= 1)
};

/// The object bins the binned builder gives a node of `refs` references: min(bins, 4 + refs / 20),
/// at least 2, the count Embree's binned builders use. Small nodes, most of the tree, bin and
/// sweep a few bins instead of `bins` (the SAH cost of the trees within 1 %, docs/BENCHMARKS.md).
inline std::uint32_t object_bin_count(std::size_t refs, std::uint32_t bins) {
  const std::size_t k = std::min<std::size_t>(bins, 4 + refs / 20);
  return std::uint32_t(std::max<std::size_t>(k, 2));
}

// A reference to a triangle: its (possibly clipped) box and original triangle id.
struct PrimRef {
  format::Box3f box;
  std::uint32_t prim;
};

struct BvhStatistics {
  std::uint64_t node_count = 0, leaf_count = 0, reference_count = 0;
  std::uint32_t max_depth = 0, max_leaf_size = 0;
  double average_leaf_size = 0, duplication_factor = 0, sah_cost = 0, bytes_per_triangle = 0;
  std::uint64_t presplit_references = 0;  // build references after a presplit (0: none)
};

// The flattened structure, ready for the blob.
struct FlatBvh {
  std::vector<format::BvhNode> nodes;
  std::vector<format::RayTriangle> triangles;
  std::vector<std::uint32_t> prim_ids;
  BvhStatistics stats;
  /// Every entry of `prim_ids` a different triangle (no spatial splits, no presplit): the
  /// collapse then takes a leaf's references as they are, without looking for repeats. False
  /// (the safe default) where that is not known.
  bool distinct_refs = false;
  /// The binned build's reference array, which it is done with once the nodes are made (empty
  /// from the other builders); its contents mean nothing. Its pages are already touched, so a
  /// collapse given it as WideCollapseOptions::scratch keeps its per-node records there instead
  /// of faulting in new blocks; reserved (not touched) to 40 bytes per 1.25 nodes a reference.
  UninitializedVector<std::byte> spare;
};

// The SBVH builder (bvh_build.cpp) over every triangle of the scene: the nodes in the flat
// layout (depth-first, first child adjacent) and, in `prim_ids`, the primitive ids in leaf
// order (leaf offsets index it; a split triangle appears once per leaf that holds a piece).
std::vector<format::BvhNode> build_sbvh_nodes(const Scene& scene, const BvhBuildOptions& options,
                                              std::vector<std::uint32_t>& prim_ids);

// The binned builder (bvh_binned_build.cpp): partitions `refs` in place into leaf order and
// returns the nodes in the flat layout, each leaf's offset indexing `refs`.
std::vector<format::BvhNode> build_binned_nodes(std::vector<PrimRef>& refs,
                                                const BvhBuildOptions& options);

// The sweep builder (bvh_sweep_build.cpp) over `refs`: returns the nodes in the flat layout
// and, in `order`, the indices into `refs` in leaf order (leaf offsets index it; they are the
// primitive ids when refs[i].prim == i, as without a presplit).
std::vector<format::BvhNode> build_sweep_nodes(std::span<const PrimRef> refs,
                                               std::vector<std::uint32_t>& order,
                                               const BvhBuildOptions& options);

// Counts, depth and SAH cost (normalised by the root's area, with the options' constants) of a
// flat BVH over `triangles` input triangles.
BvhStatistics flat_bvh_statistics(std::span<const format::BvhNode> nodes, std::size_t triangles,
                                  const BvhBuildOptions& options);

/// The BVH of `options.builder` over every triangle of the scene, in the flat layout. The
/// binned builder works in place on one reference array, the sweep builder on presorted index
/// arrays, SBVH on presorted reference arrays. With an EVH presplit (binned
/// and sweep only; SBVH throws std::invalid_argument) the builders see the pieces' references and
/// each leaf keeps one reference per triangle.
FlatBvh build_bvh(const Scene& scene, const BvhBuildOptions& options);

}  // namespace kiln
