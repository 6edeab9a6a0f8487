// Split finding for the SBVH builder (bvh_build.cpp). Costs are SAH costs relative to the node's
// half area, in units where the leaf cost of n references is n * intersection_cost.
#pragma once

#include <bit>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "kiln/compiler/bvh_builder.hpp"

namespace kiln {

/// A reference's place on an axis: its centroid's bits made to sort as unsigned integers (-0 as
/// +0), then its primitive id. A node holds each primitive at most once (the pieces of a split
/// reference go to different children), so the key orders a node's references totally.
inline std::uint64_t centroid_key(const PrimRef& r, int axis) {
  const std::uint32_t bits = std::bit_cast<std::uint32_t>(r.box.centroid(axis) + 0.0f);
  const std::uint32_t ordered = (bits & 0x80000000u) ? ~bits : bits | 0x80000000u;
  return (std::uint64_t(ordered) << 32) | r.prim;
}

/// A node's references, once per axis, each sorted by centroid_key on its axis. The arrays are
/// sorted once at the root and kept sorted through every partition (no sort per node).
struct SortedRefs {
  std::vector<PrimRef> axis[3];
  std::size_t size() const { return axis[0].size(); }
  void clear() {
    for (auto& a : axis) a = {};
  }
};

/// Sorts `refs` by centroid_key on `axis` into `out`, on up to `threads` threads (large arrays
/// in that many chunks; the keys are unique, so the order does not depend on them).
void sort_by_centroid(std::span<const PrimRef> refs, int axis, std::vector<PrimRef>& out,
                      unsigned threads = 1);

struct ObjectSplit {
  float cost = std::numeric_limits<float>::infinity();
  int axis = -1;
  std::size_t left_count = 0;  // the first left_count references sorted on `axis` go left
  format::Box3f left_box, right_box;
  bool valid() const { return axis >= 0; }
};

/// Nodes at least this large may search, partition and distribute their three axes on their
/// own threads (the `threads` arguments below; the result does not depend on them).
inline constexpr std::size_t kParallelSweep = 32768;

/// Exact SAH over the sorted centroids on all three axes (the first axis and the first position
/// win ties).
ObjectSplit find_sweep_split(const SortedRefs& refs, const format::Box3f& node_box,
                             const BvhBuildOptions& options, unsigned threads = 1);
/// Splits `refs` into the first `left_count` references on `axis` and the rest, every axis's
/// array staying sorted (a stable split by the side each reference takes on `axis`).
void partition_object_split(const SortedRefs& refs, int axis, std::size_t left_count,
                            SortedRefs& left, SortedRefs& right);
/// The same, the left child taking over `refs`'s arrays.
void partition_object_split(SortedRefs&& refs, int axis, std::size_t left_count, SortedRefs& left,
                            SortedRefs& right, unsigned threads = 1);

/// With leaves priced per packet (options.leaf_packet > 0): whether a node of n references, of
/// half area `area`, stays one leaf rather than split into `left_count` references under
/// `left_area` and the rest under `right_area`. Both sides are priced by packets, and the split
/// pays no traversal: the collapse folds a binary node into its wide parent's child slots, so a
/// split costs slots, not a node visit (with a traversal term the 8-wide trees' SAH rose by up
/// to 4 %, without it it stays within 0.1 % of a tree built down to single references).
inline bool packet_leaf_wins(const BvhBuildOptions& o, std::size_t n, float area, float left_area,
                             std::size_t left_count, float right_area) {
  const auto packets = [&](std::size_t m) {
    return float((m + o.leaf_packet - 1) / o.leaf_packet);
  };
  return left_area * packets(left_count) + right_area * packets(n - left_count) >=
         area * packets(n);
}

struct SpatialSplit {
  float cost = std::numeric_limits<float>::infinity();
  int axis = -1;
  float position = 0;
  bool valid() const { return axis >= 0; }
};

// Where spatial splits are searched, and with how many bins (measured on bunny, Lucy100k,
// Sponza and dragon_871k, docs/BENCHMARKS.md). Clipping is nearly all of an SBVH build, and
// most of it goes to small nodes, whose triangles are large against them and cross most of
// their bins, while a better plane there gains least. So: no search below kMinSpatialRefs
// references; bins / 8 below kCoarseSpatialRefs; `bins` up to kFineSpatialRefs; twice `bins`
// above (a large node's triangles cross one or two bins, and a better plane there pays for its
// whole subtree); and only on the object split's axis and the node's longest axis. Together
// the trees' SAH cost is at or below what `bins` on all three axes at every node gave.
inline constexpr std::size_t kMinSpatialRefs = 8;
inline constexpr std::size_t kCoarseSpatialRefs = 512;
inline constexpr std::size_t kFineSpatialRefs = 4096;
std::uint32_t spatial_bin_count(std::size_t refs, std::uint32_t bins);
/// A bit per axis searched: the object split's (-1: none) and the node's longest.
unsigned spatial_axes(const format::Box3f& node_box, int object_axis);

/// Stich et al. 2009: spatial bins over the node box, references clipped against bin planes,
/// on spatial_axes(node_box, object_axis) with spatial_bin_count bins. Large nodes bin fixed
/// chunks of references apart (in parallel) and merge them, so the split does not depend on
/// the thread count (`threads` of them at most). Where no plane can cost less than `to_beat`
/// (the object split's cost), judged by a lower bound from the references' boxes before any
/// clipping, no split is returned, and the split the node takes is the same.
SpatialSplit find_spatial_split(std::span<const PrimRef> refs, const format::Box3f& node_box,
                                const Scene& scene, const BvhBuildOptions& options, int object_axis,
                                unsigned threads = 1,
                                float to_beat = std::numeric_limits<float>::infinity());
/// Distributes references (visited in their order on `order_axis`), unsplitting straddlers
/// where cheaper, into children whose axis arrays stay sorted; returns the added references.
/// The left child takes `refs`' arrays (rewritten); where unsplitting leaves a side empty, both
/// children are empty and `refs` is left as it was.
std::size_t apply_spatial_split(const SpatialSplit& split, SortedRefs& refs, int order_axis,
                                const Scene& scene, SortedRefs& left, SortedRefs& right,
                                unsigned threads = 1);

/// Splits a reference's triangle (clipped to its box) by the plane axis = position.
void split_reference(const PrimRef& ref, int axis, float position, const Scene& scene,
                     format::Box3f& left, format::Box3f& right);

}  // namespace kiln
