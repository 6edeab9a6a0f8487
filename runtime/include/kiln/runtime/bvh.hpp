// A BVH (kind "bvh" or "sbvh") straight on its mapped sections: ray traversal, and the
// proximity, containment and range queries.
#pragma once

#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "kiln/formats/bvh.hpp"
#include "kiln/formats/geometry.hpp"
#include "kiln/runtime/query_results.hpp"
#include "kiln/runtime/ray.hpp"

namespace kiln {

class Blob;

/// A validated view of one BVH's arrays; a RayStructure (kiln/runtime/ray_structure.hpp).
/// Creating it walks the node array once (O(nodes)): every node is reached exactly once in
/// depth-first order, no deeper than the traversal stack, and every leaf range lies inside the
/// reference arrays; so traversal cannot read out of range, loop or overflow its stack, whatever
/// the bytes. Throws BlobError otherwise.
class BvhView {
 public:
  using HitType = Hit;

  BvhView(std::span<const format::BvhNode> nodes, std::span<const format::RayTriangle> triangles,
          std::span<const std::uint32_t> prim_ids, const std::string& name = "bvh");
  /// The structure named `name` of a blob; throws BlobError when the blob has no structure of
  /// that name or it is not a BVH.
  static BvhView from_blob(const Blob& blob, const std::string& name);

  /// Closest hit in (tmin, tmax); Hit::prim == kNoHit on a miss.
  Hit intersect(const Ray& ray) const;
  /// The first hit found in (tmin, tmax), not necessarily the closest.
  Hit intersect_any(const Ray& ray) const;
  /// Whether anything lies in (tmin, tmax).
  bool occluded(const Ray& ray) const;
  /// The closest hit, adding its node visits and triangle tests to `cost`.
  Hit intersect_counting(const Ray& ray, Cost& cost) const;

  std::span<const format::BvhNode> nodes() const { return nodes_; }
  std::span<const format::RayTriangle> triangles() const { return triangles_; }
  std::span<const std::uint32_t> prim_ids() const { return prim_ids_; }

 private:
  std::span<const format::BvhNode> nodes_;
  std::span<const format::RayTriangle> triangles_;
  std::span<const std::uint32_t> prim_ids_;
};

/// The closest point of the surface within `max_distance`. Branch and bound: nodes are visited
/// nearest box first and pruned by box distance. Ties go to the lower primitive id.
ClosestPoint closest_point(const BvhView& bvh, const format::Float3& p,
                           float max_distance = std::numeric_limits<float>::infinity());

/// Every triangle that intersects the box (exact separating-axis test, Akenine-Moller 2001),
/// as sorted, unique original primitive ids, into `out` (cleared first).
void triangles_in_box(const BvhView& bvh, const format::Float3& lo, const format::Float3& hi,
                      std::vector<std::uint32_t>& out);

/// Inside/outside by ray parity: five rays in fixed, irrational directions, each counting the
/// distinct triangles it crosses; the majority wins. Meaningful for closed meshes; on an open
/// mesh it still answers (the blob's input says whether the mesh is closed).
bool point_inside(const BvhView& bvh, const format::Float3& p);

}  // namespace kiln
