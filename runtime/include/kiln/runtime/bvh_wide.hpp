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
/// What kAuto resolves to: KILN_BVH_KERNEL (scalar|sse|avx2|avx512) when set, else the best
/// kernel this CPU supports. Throws std::invalid_argument for an unknown or unsupported value.
BvhKernel bvh_auto_kernel();

/// One kernel's entry points for one width (runtime/src/bvh_wide_kernels.hpp).
struct BvhWideKernel {
  Hit (*closest)(const BvhWideView&, const Ray&);
  Hit (*any)(const BvhWideView&, const Ray&);
  Hit (*counting)(const BvhWideView&, const Ray&, Cost&);
};

/// A validated view of one wide BVH's arrays; a RayStructure (kiln/runtime/ray_structure.hpp).
/// Creating it walks the nodes once (O(nodes)): every node is reached exactly once in depth-first
/// order, no deeper than format::kBvhMaxDepth, every child word names a node or a packet range
/// inside the arrays, and leaves consume the packets in order; so no kernel can read out of
/// range, loop or overflow its fixed stack, whatever the bytes. Throws BlobError otherwise.
class BvhWideView {
 public:
  using HitType = Hit;

  /// `nodes` holds BvhNode4 or BvhNode8 (width 4 or 8), or BvhQNode4/8 when `quantized`;
  /// `prim_ids` one id per packet lane.
  BvhWideView(std::uint32_t width, bool quantized, std::span<const std::byte> nodes,
              std::span<const format::BvhTrianglePacket> packets,
              std::span<const std::uint32_t> prim_ids, const std::string& name = "bvh",
              BvhKernel kernel = BvhKernel::kAuto);
  /// The structure named `name` of a blob; throws BlobError when it is not a wide BVH.
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
  /// The nodes as the type they are (by width and quantized()); empty for the other types.
  std::span<const format::BvhNode4> nodes4() const { return nodes_as<format::BvhNode4>(4, false); }
  std::span<const format::BvhNode8> nodes8() const { return nodes_as<format::BvhNode8>(8, false); }
  std::span<const format::BvhQNode4> qnodes4() const {
    return nodes_as<format::BvhQNode4>(4, true);
  }
  std::span<const format::BvhQNode8> qnodes8() const {
    return nodes_as<format::BvhQNode8>(8, true);
  }
  std::span<const std::byte> node_bytes() const { return nodes_; }
  std::span<const format::BvhTrianglePacket> packets() const { return packets_; }
  std::span<const std::uint32_t> prim_ids() const { return prim_ids_; }

 private:
  template <class Node>
  std::span<const Node> nodes_as(std::uint32_t width, bool quantized) const {
    if (width_ != width || quantized_ != quantized) return {};
    return {reinterpret_cast<const Node*>(nodes_.data()), node_count_};
  }

  std::uint32_t width_;
  bool quantized_ = false;
  std::size_t node_count_ = 0;
  std::span<const std::byte> nodes_;
  std::span<const format::BvhTrianglePacket> packets_;
  std::span<const std::uint32_t> prim_ids_;
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
