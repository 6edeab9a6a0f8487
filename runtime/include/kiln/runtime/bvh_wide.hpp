// The wide BVH (kinds "bvh" and "sbvh" built with width 4 or 8) straight on its mapped sections:
// ray traversal by a SIMD kernel picked at run time, and the proximity, containment and range
// queries.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "kiln/formats/bvh_wide.hpp"
#include "kiln/formats/geometry.hpp"
#include "kiln/runtime/query_results.hpp"
#include "kiln/runtime/ray.hpp"

namespace kiln {

class Blob;
class BvhWideView;

/// The traversal kernels of a wide BVH. All read the same bytes and give the same hits (the same
/// per-triangle arithmetic, in the same order); they differ in the instructions.
enum class BvhKernel { kAuto, kScalar, kSse, kAvx2, kAvx512 };

/// "auto", "scalar", "sse", "avx2", "avx512".
const char* bvh_kernel_name(BvhKernel kernel);
/// Whether this CPU (and this build) can run `kernel`; kAuto and kScalar always can.
bool bvh_kernel_supported(BvhKernel kernel);
/// What kAuto resolves to for nodes of `width` children: KILN_BVH_KERNEL (scalar|sse|avx2|avx512)
/// when set, else the best kernel this CPU supports (AVX2 before AVX-512 for width 4 and 8,
/// AVX-512 first for 16). Throws std::invalid_argument for an unknown or unsupported value.
BvhKernel bvh_auto_kernel(std::uint32_t width = 8);

/// One kernel's entry points for one width (runtime/src/bvh_wide_kernels.hpp).
struct BvhWideKernel {
  Hit (*closest)(const BvhWideView&, const Ray&);
  Hit (*any)(const BvhWideView&, const Ray&);
  Hit (*counting)(const BvhWideView&, const Ray&, Cost&);
};

/// A validated view of one wide BVH's arena (kiln/formats/bvh_wide.hpp); a RayStructure
/// (kiln/runtime/ray_structure.hpp). Creating it walks the arena once (O(size)): every node and
/// leaf packet sits exactly where the depth-first layout puts it, no node deeper than
/// format::kBvhMaxDepth, every interior child's prefetch hint is its leaf packets' line count,
/// and the nodes, packets and padding fill the arena; so no kernel can read out of range, loop or
/// overflow its fixed stack, whatever the bytes. Throws BlobError otherwise.
class BvhWideView {
 public:
  using HitType = Hit;

  /// `arena` holds BvhNode4, BvhNode8 or BvhNode16 nodes (width 4, 8 or 16), or BvhQNode4/8
  /// when `quantized` (width 4 or 8), and their leaves' BvhTrianglePackets.
  BvhWideView(std::uint32_t width, bool quantized, std::span<const std::byte> arena,
              const std::string& name = "bvh", BvhKernel kernel = BvhKernel::kAuto);
  /// The structure named `name` of a blob; throws BlobError when it is not a wide BVH, or one
  /// of the layout before the arena (written before 2026-11-27: rebuild it).
  static BvhWideView from_blob(const Blob& blob, const std::string& name,
                               BvhKernel kernel = BvhKernel::kAuto);

  /// Closest hit in (tmin, tmax); Hit::prim == kNoHit on a miss.
  Hit intersect(const Ray& ray) const { return kernel_->closest(*this, ray); }
  /// The first hit found in (tmin, tmax), not necessarily the closest (children unordered).
  Hit intersect_any(const Ray& ray) const { return kernel_->any(*this, ray); }
  /// Whether anything lies in (tmin, tmax).
  bool occluded(const Ray& ray) const { return kernel_->any(*this, ray).hit(); }
  /// The closest hit, adding wide-node visits and triangle (lane) tests to `cost`.
  Hit intersect_counting(const Ray& ray, Cost& cost) const {
    return kernel_->counting(*this, ray, cost);
  }

  std::uint32_t width() const { return width_; }
  bool quantized() const { return quantized_; }
  BvhKernel kernel() const { return kernel_id_; }
  std::size_t node_count() const { return node_count_; }
  std::size_t packet_count() const { return packet_count_; }
  std::span<const std::byte> arena() const { return arena_; }

  /// The node a child word names (the root: 0), as `Node` (BvhNode4/8/16 or BvhQNode4/8, by
  /// width() and quantized()).
  template <class Node>
  const Node& node(std::uint32_t word) const {
    return *reinterpret_cast<const Node*>(arena_.data() +
                                          std::size_t(word) * format::kBvhArenaUnit);
  }
  /// The packets of a leaf child (its word and packet count).
  std::span<const format::BvhTrianglePacket> leaf(std::uint32_t word, std::uint32_t packets) const {
    return {reinterpret_cast<const format::BvhTrianglePacket*>(
                arena_.data() + std::size_t(word & ~format::kBvhLeafFlag) * format::kBvhArenaUnit),
            packets};
  }
  /// Calls visit(node) for every node as `Node`, in depth-first pre-order.
  template <class Node, class Visit>
  void for_each_node(Visit&& visit) const {
    std::vector<std::uint32_t> pending{0};
    while (!pending.empty()) {
      const Node& n = node<Node>(pending.back());
      pending.pop_back();
      visit(n);
      for (int k = int(sizeof n.child / sizeof n.child[0]) - 1; k >= 0; --k)
        if (!(n.child[k] & format::kBvhLeafFlag)) pending.push_back(n.child[k]);
    }
  }

 private:
  std::uint32_t width_;
  bool quantized_ = false;
  std::size_t node_count_ = 0, packet_count_ = 0;
  std::span<const std::byte> arena_;
  BvhKernel kernel_id_ = BvhKernel::kScalar;
  const BvhWideKernel* kernel_ = nullptr;
};

/// The closest point of the surface within `max_distance` (branch and bound, nearest box first;
/// ties go to the lower primitive id).
ClosestPoint closest_point(const BvhWideView& bvh, const format::Float3& p,
                           float max_distance = std::numeric_limits<float>::infinity());
/// Every triangle that intersects the box, as sorted, unique primitive ids, into `out`.
void triangles_in_box(const BvhWideView& bvh, const format::Float3& lo, const format::Float3& hi,
                      std::vector<std::uint32_t>& out);
/// Inside/outside by ray parity, as point_inside(const BvhView&, ...) decides it.
bool point_inside(const BvhWideView& bvh, const format::Float3& p);

}  // namespace kiln
