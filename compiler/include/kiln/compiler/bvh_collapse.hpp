// Collapse of a binary BVH (FlatBvh, kiln/compiler/bvh_builder.hpp) into the wide layout of
// kiln/formats/bvh_wide.hpp: 4 or 8 children per node, leaf triangles in packets of four, laid
// out as one arena.
#pragma once

#include <cstdint>
#include <vector>

#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/compiler/uninitialized_allocator.hpp"
#include "kiln/formats/bvh_wide.hpp"

namespace kiln {

/// Statistics of a wide BVH, beside the binary tree's (BvhStatistics) it came from.
struct WideBvhStatistics {
  std::uint64_t node_count = 0, leaf_count = 0, packet_count = 0;
  std::uint32_t max_depth = 0;
  double packet_fill = 0;  ///< distinct references per leaf / (packets x 4)
  /// The tree's SAH cost by the programme's model (node_cost per wide node, packet_cost per
  /// packet, leaf_cost per leaf, each weighted by its box's area over the root's); 0 if greedy.
  double sah_cost = 0;
  std::uint64_t arena_bytes = 0;  ///< the stored arena: nodes, packets (with ids), padding
  double bytes_per_triangle = 0;  ///< arena_bytes / triangles
};

/// A collapsed BVH. `arena` is what the blob stores (the BVWA section, kiln/formats/bvh_wide.hpp).
/// The same tree by index, for tests and tools: `nodes` holds node_count nodes of `width`
/// children as raw bytes (BvhNode4/8, or BvhQNode4/8 when quantized) in depth-first pre-order,
/// whose child words are node indices and leaf packet indices into `packets` instead of arena
/// offsets (interior children's `packets` 0). The arena's every byte is written (padding as
/// zeros), so it is made without zeroing first.
struct FlatWideBvh {
  std::uint32_t width = 8;
  bool quantized = false;  ///< nodes are BvhQNode4/8 (8-bit child boxes) instead of float ones
  UninitializedVector<std::byte> arena;
  std::vector<std::byte> nodes;
  std::vector<format::BvhTrianglePacket> packets;
  WideBvhStatistics stats;
};

/// The order of a wide node's child slots. Closest-hit traversal sorts the entered children by
/// distance; any-hit traversal (shadow rays) visits them in slot order, so the order decides how
/// soon an occluder is found.
enum class WideSlotOrder {
  kTree,         ///< the binary tree's order (left before right)
  kLargestArea,  ///< by decreasing surface area
  /// By decreasing P / C: P = min(1, triangle area / half the box area), a crude chance that a
  /// ray through the child's box hits a triangle in it, over C = the child's SAH cost per ray
  /// entering it (Ylitie's programme; with the greedy collapse, area x (1 + references / 4)), the
  /// expected work to find out. Finds occluders sooner than either above, inside and outside
  /// Crytek Sponza alike (docs/BENCHMARKS.md).
  kOcclusion,
};

/// How the binary tree is cut into wide nodes and leaves.
struct WideCollapseOptions {
  /// false: the SAH dynamic programme below; true: the greedy expansion (for comparison).
  bool greedy = false;
  double node_cost = 1.0;    ///< SAH cost of visiting one wide node (all its child boxes)
  double packet_cost = 0.5;  ///< SAH cost of testing one packet of four triangles
  double leaf_cost = 0.0;    ///< SAH cost of entering a leaf, beyond its packets
  /// A binary subtree of at most this many references may become one leaf.
  std::uint32_t max_leaf_refs = 16;
  WideSlotOrder order = WideSlotOrder::kOcclusion;
  /// Worker threads for the passes that run in parallel (0 = every core); never changes the
  /// result.
  unsigned threads = 1;
  /// Also fill FlatWideBvh::nodes and packets (the tree by index, for tests and tools); off,
  /// only the arena is made (what a blob stores), without a second copy of the tree.
  bool index_tree = true;
  /// Where the collapse keeps its per-node records (and per-reference areas) while there is
  /// room: FlatBvh::spare, the binned build's reference array, whose pages are already touched
  /// (a new block's pages each fault on first write). Null: blocks of its own. Its contents
  /// are overwritten; one collapse at a time per block.
  UninitializedVector<std::byte>* scratch = nullptr;
};

/// Collapses `binary` into `width` (4, 8 or 16; 16 with float boxes only) children per node.
/// Default: the dynamic programme of Ylitie, Karras and Laine (2017) over the binary tree, which
/// picks for every subtree the cheapest way to spread it over at most `width` child slots, each
/// slot a wide node (area x node_cost plus its own children) or a leaf priced by its packets (area
/// x (leaf_cost + packet_cost x ceil(refs / 4))), so leaves fill their packets where the SAH
/// allows. `options.greedy`: each wide node opens the child of largest surface area until it has
/// `width` children, and a binary subtree of at most four references becomes one leaf packet.
/// Either way a triangle in two binary leaves of one wide leaf is stored once (SBVH, presplit).
/// Deterministic: the same bytes on any `options.threads`. `binary.nodes` must be in depth-first
/// pre-order with the first child adjacent, as the builders emit them (the programme throws
/// std::invalid_argument where it finds them out of that order). `triangle_count` is the scene's
/// (for bytes per triangle). `quantized`: child boxes as bytes relative to the node
/// (BvhQuantizedNode), each containing the float box. Corners come from `binary.triangles`, or,
/// when it is empty (built with BvhBuildOptions::leaf_triangles off), from `scene` through the
/// primitive ids. The result holds the arena and, with `options.index_tree`, the same tree by
/// index. Throws std::invalid_argument for another width, a leaf over 1020 references, (quantized)
/// coordinates beyond 1e38, an arena beyond 32 GiB, or no source of corners.
FlatWideBvh collapse_bvh(const FlatBvh& binary, std::uint32_t width, std::size_t triangle_count,
                         bool quantized = false, const Scene* scene = nullptr,
                         const WideCollapseOptions& options = {});

}  // namespace kiln
