// Traversal of a SAH k-d tree straight on its mapped sections.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "kiln/formats/kdtree.hpp"
#include "kiln/runtime/ray.hpp"

namespace kiln {

class Blob;

// A validated view of one k-d tree. Creating it walks the nodes once and reads every reference
// (O(nodes + references)): nodes in depth-first order, no deeper than the traversal stack, leaf
// ranges consecutive and in range, primitive ids naming stored triangles; so traversal cannot
// read out of range, loop or overflow its stack, whatever the bytes. Throws BlobError otherwise.
class KdTreeView {
 public:
  KdTreeView(std::span<const format::KdNode> nodes, std::span<const std::uint32_t> prim_ids,
             std::span<const format::RayTriangle> triangles, const float bounds_min[3],
             const float bounds_max[3], const std::string& name = "kdtree");
  // The k-d tree named `name` in a blob; throws BlobError when absent.
  static KdTreeView from_blob(const Blob& blob, const std::string& name);

  // Closest hit in (tmin, tmax); Hit::prim == kNoHit on a miss.
  Hit intersect(const Ray& ray) const;
  // Any hit in (tmin, tmax), stopping at the first found.
  bool occluded(const Ray& ray, float* t = nullptr) const;

  // Node visits and triangle tests of one closest-hit query (for heatmaps and statistics).
  struct Cost {
    std::uint32_t nodes = 0, triangles = 0;
  };
  Hit intersect_counting(const Ray& ray, Cost& cost) const;

  std::span<const format::KdNode> nodes() const { return nodes_; }
  std::span<const std::uint32_t> prim_ids() const { return prim_ids_; }
  std::span<const format::RayTriangle> triangles() const { return triangles_; }
  const float* bounds_min() const { return min_; }
  const float* bounds_max() const { return max_; }

 private:
  std::span<const format::KdNode> nodes_;
  std::span<const std::uint32_t> prim_ids_;
  std::span<const format::RayTriangle> triangles_;
  float min_[3], max_[3];
};

// Closest hits (or any hits) for many rays on up to `threads` threads (0 = all cores).
void trace_rays(const KdTreeView& tree, std::span<const Ray> rays, std::span<Hit> hits,
                bool any_hit, unsigned threads);

}  // namespace kiln
