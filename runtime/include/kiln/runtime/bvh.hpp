// Traversal of a BVH (bvh or sbvh) straight on its mapped sections.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "kiln/formats/bvh.hpp"
#include "kiln/runtime/ray.hpp"

namespace kiln {

class Blob;

// A validated view of one BVH's arrays. Creating it walks the node array once (O(nodes)):
// every node is reached exactly once in depth-first order, no deeper than the traversal stack,
// and every leaf range lies inside the reference arrays; so traversal cannot read out of
// range, loop or overflow its stack, whatever the bytes. Throws BlobError otherwise.
class BvhView {
 public:
  BvhView(std::span<const format::BvhNode> nodes, std::span<const format::RayTriangle> triangles,
          std::span<const std::uint32_t> prim_ids, const std::string& name = "bvh");
  // The structure named `name` ("bvh", "sbvh") in a blob; throws BlobError when absent.
  static BvhView from_blob(const Blob& blob, const std::string& name);

  // Closest hit in (tmin, tmax); Hit::prim == kNoHit on a miss.
  Hit intersect(const Ray& ray) const;
  // Any hit in (tmin, tmax), stopping at the first found; writes its distance to `t`.
  bool occluded(const Ray& ray, float* t = nullptr) const;

  // Node visits and triangle tests of one closest-hit query (for heatmaps and statistics).
  struct Cost {
    std::uint32_t nodes = 0, triangles = 0;
  };
  Hit intersect_counting(const Ray& ray, Cost& cost) const;

  std::span<const format::BvhNode> nodes() const { return nodes_; }
  std::span<const format::RayTriangle> triangles() const { return triangles_; }
  std::span<const std::uint32_t> prim_ids() const { return prim_ids_; }

 private:
  std::span<const format::BvhNode> nodes_;
  std::span<const format::RayTriangle> triangles_;
  std::span<const std::uint32_t> prim_ids_;
};

// Closest hits (or any hits) for many rays on up to `threads` threads (0 = all cores).
// Results do not depend on the thread count.
void trace_rays(const BvhView& bvh, std::span<const Ray> rays, std::span<Hit> hits, bool any_hit,
                unsigned threads);

}  // namespace kiln
