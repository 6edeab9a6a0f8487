// Collapse of a binary BVH (FlatBvh, kiln/compiler/bvh_builder.hpp) into the wide layout of
// kiln/formats/bvh_wide.hpp: 4 or 8 children per node, leaf triangles in packets of four.
#pragma once

#include <cstdint>
#include <vector>

#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/formats/bvh_wide.hpp"

namespace kiln {

/// Statistics of a wide BVH, beside the binary tree's (BvhStatistics) it came from.
struct WideBvhStatistics {
  std::uint64_t node_count = 0, leaf_count = 0, packet_count = 0;
  std::uint32_t max_depth = 0;
  double packet_fill = 0;         ///< distinct references per leaf / (packets x 4)
  double bytes_per_triangle = 0;  ///< nodes + packets + per-lane primitive ids
};

/// A collapsed BVH ready for the blob: `nodes` holds node_count nodes of `width` children as raw
/// bytes (BvhNode4/8, or BvhQNode4/8 when quantized), `prim_ids` one original triangle id per
/// packet lane.
struct FlatWideBvh {
  std::uint32_t width = 8;
  bool quantized = false;  ///< nodes are BvhQNode4/8 (8-bit child boxes) instead of float ones
  std::vector<std::byte> nodes;
  std::vector<format::BvhTrianglePacket> packets;
  std::vector<std::uint32_t> prim_ids;
  WideBvhStatistics stats;
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
  /// A wide node's slots by decreasing surface area, as Embree orders its children "for faster
  /// shadow rays": the any-hit traversal enters the lowest slot first, and the largest child is
  /// the likeliest to hold an occluder (closest-hit rays sort by distance anyway). false: the
  /// binary tree's order.
  bool largest_first = true;
};

/// Collapses `binary` into `width` (4 or 8) children per node. Default: the dynamic programme of
/// Ylitie, Karras and Laine (2017) over the binary tree, which picks for every subtree the
/// cheapest way to spread it over at most `width` child slots, each slot a wide node (area x
/// node_cost plus its own children) or a leaf priced by its packets (area x (leaf_cost +
/// packet_cost x ceil(refs / 4))), so leaves fill their packets where the SAH allows.
/// `options.greedy`: each wide node opens the child of largest surface area until it has `width`
/// children, and a binary subtree of at most four references becomes one leaf packet. Either way a
/// triangle in two binary leaves of one wide leaf is stored once (SBVH, presplit). Deterministic
/// and serial. `triangle_count` is the scene's (for bytes per triangle). `quantized`: child boxes
/// as bytes relative to the node (BvhQuantizedNode), each containing the float box. Corners come
/// from `binary.triangles`, or, when it is empty (built with BvhBuildOptions::leaf_triangles off),
/// from `scene` through the primitive ids. Throws std::invalid_argument for another width, a leaf
/// over 1020 references, (quantized) coordinates beyond 1e38, or no source of corners.
FlatWideBvh collapse_bvh(const FlatBvh& binary, std::uint32_t width, std::size_t triangle_count,
                         bool quantized = false, const Scene* scene = nullptr,
                         const WideCollapseOptions& options = {});

}  // namespace kiln
