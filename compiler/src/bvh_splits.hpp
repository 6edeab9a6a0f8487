// Split finding for the BVH builders. Costs are SAH costs relative to the node's half area,
// in units where the leaf cost of n references is n * intersection_cost.
#pragma once

#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "kiln/compiler/bvh_builder.hpp"

namespace kiln {

struct ObjectSplit {
  float cost = std::numeric_limits<float>::infinity();
  int axis = -1;
  // Binned: references whose centroid bin is <= bin go left. Sweep: the first `left_count`
  // references of the refs sorted on `axis` go left.
  std::uint32_t bin = 0;
  float bin_scale = 0, bin_origin = 0;
  std::size_t left_count = 0;
  format::Box3f left_box, right_box;
  bool valid() const { return axis >= 0; }
};

// Wald 2007: centroid bins on all three axes.
ObjectSplit find_binned_split(std::span<const PrimRef> refs, const format::Box3f& node_box,
                              const BvhBuildOptions& options);
// Exact SAH over sorted centroids on all three axes. Leaves `refs` sorted on the chosen axis
// (stable, ties by primitive id), so the split is a prefix.
ObjectSplit find_sweep_split(std::vector<PrimRef>& refs, const format::Box3f& node_box,
                             const BvhBuildOptions& options);
// Partitions by a binned split, keeping relative order.
void apply_binned_split(const ObjectSplit& split, std::vector<PrimRef>& refs,
                        std::vector<PrimRef>& left, std::vector<PrimRef>& right);

struct SpatialSplit {
  float cost = std::numeric_limits<float>::infinity();
  int axis = -1;
  float position = 0;
  bool valid() const { return axis >= 0; }
};

// Stich et al. 2009: spatial bins over the node box, references clipped against bin planes.
SpatialSplit find_spatial_split(std::span<const PrimRef> refs, const format::Box3f& node_box,
                                const Scene& scene, const BvhBuildOptions& options);
// Distributes references, unsplitting straddlers where cheaper; returns the added references.
std::size_t apply_spatial_split(const SpatialSplit& split, std::span<const PrimRef> refs,
                                const Scene& scene, std::vector<PrimRef>& left,
                                std::vector<PrimRef>& right);

// Splits a reference's triangle (clipped to its box) by the plane axis = position.
void split_reference(const PrimRef& ref, int axis, float position, const Scene& scene,
                     format::Box3f& left, format::Box3f& right);

}  // namespace kiln
