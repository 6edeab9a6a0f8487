// The binned builder's entry points on its own 32-byte references (bvh_build_simd.hpp).
#pragma once

#include <span>
#include <vector>

#include "bvh_build_simd.hpp"
#include "kiln/compiler/bvh_builder.hpp"

namespace kiln {

/// One reference per triangle of the scene (its box, its index), built in parallel.
bvh_simd::BuildRefs triangle_build_refs(const Scene& scene, unsigned threads);

/// The binned SAH builder over `refs`, which it partitions in place into leaf order; returns
/// the nodes in the flat layout, each leaf's offset indexing `refs`. Byte-identical for any
/// thread count, and the same tree as build_binned_nodes over the same references as PrimRef.
std::vector<format::BvhNode> build_binned_nodes(std::span<bvh_simd::BuildRef> refs,
                                                const BvhBuildOptions& options);

}  // namespace kiln
