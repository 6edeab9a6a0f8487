// A SAH k-d tree straight on its mapped sections: ray traversal, and the proximity, containment
// and range queries.
#pragma once

#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "kiln/formats/geometry.hpp"
#include "kiln/formats/kdtree.hpp"
#include "kiln/runtime/query_results.hpp"
#include "kiln/runtime/ray.hpp"

namespace kiln {

class Blob;

/// A validated view of one k-d tree; a RayStructure (kiln/runtime/ray_structure.hpp). Creating
/// it walks the nodes once and reads every reference (O(nodes + references)): nodes in
/// depth-first order, no deeper than the traversal stack, leaf ranges consecutive and in range,
/// primitive ids naming stored triangles; so traversal cannot read out of range, loop or
/// overflow its stack, whatever the bytes. Throws BlobError otherwise.
class KdTreeView {
 public:
  using HitType = Hit;

  KdTreeView(std::span<const format::KdNode> nodes, std::span<const std::uint32_t> prim_ids,
             std::span<const format::RayTriangle> triangles, const format::Box3f& bounds,
             const std::string& name = "kdtree");
  /// The structure named `name` of a blob; throws BlobError when the blob has no structure of
  /// that name or it is not a k-d tree.
  static KdTreeView from_blob(const Blob& blob, const std::string& name);

  /// Closest hit in (tmin, tmax); Hit::prim == kNoHit on a miss.
  Hit intersect(const Ray& ray) const;
  /// The first hit found in (tmin, tmax), not necessarily the closest.
  Hit intersect_any(const Ray& ray) const;
  /// Whether anything lies in (tmin, tmax).
  bool occluded(const Ray& ray) const;
  /// The closest hit, adding its node visits and triangle tests to `cost`.
  Hit intersect_counting(const Ray& ray, Cost& cost) const;

  std::span<const format::KdNode> nodes() const { return nodes_; }
  std::span<const std::uint32_t> prim_ids() const { return prim_ids_; }
  std::span<const format::RayTriangle> triangles() const { return triangles_; }
  /// The root cell.
  const format::Box3f& bounds() const { return bounds_; }

 private:
  std::span<const format::KdNode> nodes_;
  std::span<const std::uint32_t> prim_ids_;
  std::span<const format::RayTriangle> triangles_;
  format::Box3f bounds_;
};

/// The proximity queries, with the same answers and tie rules as on any triangle structure:
/// cells are walked from the tree's root bounds (nearest cell first for the closest point,
/// pruned by cell distance), and the whole triangles a leaf references are tested. A point
/// outside the root bounds is fine.
/// The closest point of the surface within `max_distance`; ties go to the lower primitive id.
ClosestPoint closest_point(const KdTreeView& tree, const format::Float3& p,
                           float max_distance = std::numeric_limits<float>::infinity());
/// Every triangle that intersects the box, as sorted, unique primitive ids, into `out`.
void triangles_in_box(const KdTreeView& tree, const format::Float3& lo, const format::Float3& hi,
                      std::vector<std::uint32_t>& out);
/// Inside/outside by a majority of five ray-parity votes (meaningful for closed meshes).
bool point_inside(const KdTreeView& tree, const format::Float3& p);

}  // namespace kiln
