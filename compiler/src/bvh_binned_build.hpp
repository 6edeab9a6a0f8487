// The binned builder's entry points on its own 32-byte references (bvh_build_simd.hpp).
#pragma once

#include <span>
#include <vector>

#include "bvh_build_simd.hpp"
#include "kiln/compiler/bvh_builder.hpp"

namespace kiln {

/// One reference per triangle of the scene (its box, its index), built in parallel into `block`,
/// which is sized for them and reserved for `reserve_bytes` (for a later use of its memory).
std::span<bvh_simd::BuildRef> triangle_build_refs(const Scene& scene, unsigned threads,
                                                  UninitializedVector<std::byte>& block,
                                                  std::size_t reserve_bytes);

/// The binned SAH builder over `refs`, which it partitions in place into leaf order; returns
/// the nodes in the flat layout, each leaf's offset indexing `refs`. Byte-identical for any
/// thread count, and the same tree as build_binned_nodes over the same references as PrimRef.
/// With `counts`, also the nodes' counts, depth and SAH cost as flat_bvh_statistics gives them
/// (node_count, leaf_count, reference_count, max_depth, max_leaf_size, sah_cost), counted while
/// the nodes are emitted instead of in a pass after. With `prim_ids` (as long as `refs`), also
/// each reference's primitive in leaf order, written as its leaf is made (while its references
/// are in cache) instead of in a pass over them all after.
std::vector<format::BvhNode> build_binned_nodes(std::span<bvh_simd::BuildRef> refs,
                                                const BvhBuildOptions& options,
                                                BvhStatistics* counts = nullptr,
                                                std::span<std::uint32_t> prim_ids = {});

/// Half the surface area of a flat node's box, in double (0 for an empty box): the statistics'.
inline double bvh_node_half_area(const format::BvhNode& n) {
  const double dx = double(n.max[0]) - n.min[0], dy = double(n.max[1]) - n.min[1],
               dz = double(n.max[2]) - n.min[2];
  return dx < 0 || dy < 0 || dz < 0 ? 0.0 : dx * dy + dy * dz + dz * dx;
}

/// A node's term of the statistics' SAH cost: its area relative to the root's, times a test per
/// reference (a leaf) or a traversal step (an interior node).
inline double bvh_sah_term(const format::BvhNode& n, bool leaf, double root_area,
                           const BvhBuildOptions& options) {
  const double area = root_area > 0 ? bvh_node_half_area(n) / root_area : 0.0;
  return leaf ? area * options.intersection_cost * double(n.count) : area * options.traversal_cost;
}

}  // namespace kiln
