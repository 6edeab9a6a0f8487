// The uniform grid and the two-level grid straight on their mapped sections: ray traversal (the
// 3D-DDA of kiln/runtime/grid_dda.hpp at every level) and the proximity, containment and range
// queries.
#pragma once

#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "kiln/formats/grid.hpp"
#include "kiln/runtime/grid_dda.hpp"
#include "kiln/runtime/query_results.hpp"
#include "kiln/runtime/ray.hpp"

namespace kiln {

class Blob;

/// Compressed-row cell lists: cell c holds refs[offsets[c] .. offsets[c + 1]).
struct GridLists {
  std::span<const std::uint32_t> offsets;  // cells + 1
  std::span<const std::uint32_t> refs;

  std::span<const std::uint32_t> cell(std::uint64_t c) const {
    return refs.subspan(offsets[c], offsets[c + 1] - offsets[c]);
  }
};

/// A validated view of one uniform grid; a RayStructure (kiln/runtime/ray_structure.hpp).
/// Creating it checks the box (finite, positive extent), the resolution (each axis in
/// 1..kGridMaxAxis, at most kGridMaxCells cells), offsets (cells + 1 of them, from 0, never
/// decreasing, ending at the reference count) and every reference (naming a stored triangle),
/// O(cells + references); so no query can read out of range or loop, whatever the bytes.
/// Throws BlobError otherwise.
class GridView {
 public:
  using HitType = Hit;

  GridView(const GridFrame& frame, GridLists lists, std::span<const format::RayTriangle> triangles,
           const std::string& name = "grid");
  /// The structure named `name` of a blob; throws BlobError when the blob has no structure of
  /// that name or it is not a uniform grid.
  static GridView from_blob(const Blob& blob, const std::string& name);

  /// Closest hit in (tmin, tmax); Hit::prim == kNoHit on a miss.
  Hit intersect(const Ray& ray) const;
  /// The first hit found in (tmin, tmax), not necessarily the closest.
  Hit intersect_any(const Ray& ray) const;
  /// Whether anything lies in (tmin, tmax).
  bool occluded(const Ray& ray) const;
  /// The closest hit, adding its cell visits and triangle tests to `cost`.
  Hit intersect_counting(const Ray& ray, Cost& cost) const;

  const GridFrame& frame() const { return frame_; }
  const GridLists& lists() const { return lists_; }
  std::span<const format::RayTriangle> triangles() const { return triangles_; }

 private:
  GridFrame frame_;
  GridLists lists_;
  std::span<const format::RayTriangle> triangles_;
};

/// A validated view of one two-level grid; a RayStructure. Creating it checks the top frame as
/// GridView does, every leaf descriptor (resolution 0 0 0 for an empty top cell, else each axis
/// in 1..kGridMaxAxis; leaf cells consecutive in top-cell order, their total equal to the
/// offsets' cells), the offsets and references as GridView does. Throws BlobError otherwise.
class NestedGridView {
 public:
  using HitType = Hit;

  NestedGridView(const GridFrame& top, std::span<const format::LeafGrid> leaves, GridLists lists,
                 std::span<const format::RayTriangle> triangles,
                 const std::string& name = "nested-grid");
  static NestedGridView from_blob(const Blob& blob, const std::string& name);

  Hit intersect(const Ray& ray) const;
  Hit intersect_any(const Ray& ray) const;
  bool occluded(const Ray& ray) const;
  /// Top and leaf cell visits count as node visits.
  Hit intersect_counting(const Ray& ray, Cost& cost) const;

  const GridFrame& frame() const { return top_; }
  std::span<const format::LeafGrid> leaves() const { return leaves_; }
  const GridLists& lists() const { return lists_; }
  std::span<const format::RayTriangle> triangles() const { return triangles_; }
  /// The grid of top cell `c` (its box, its descriptor's resolution).
  GridFrame leaf_frame(const std::uint32_t c[3]) const {
    return top_.cell_frame(c, leaves_[top_.linear(c)].res);
  }

 private:
  GridFrame top_;
  std::span<const format::LeafGrid> leaves_;
  GridLists lists_;
  std::span<const format::RayTriangle> triangles_;
};

/// The proximity queries, with the same answers and tie rules as on any triangle structure. The
/// builder lists a triangle in every cell whose (slightly padded) closed box it meets, so each
/// point of a triangle lies in a cell listing it.
/// The closest point of the surface within `max_distance`; ties go to the lower primitive id.
ClosestPoint closest_point(const GridView& grid, const format::Float3& p,
                           float max_distance = std::numeric_limits<float>::infinity());
ClosestPoint closest_point(const NestedGridView& grid, const format::Float3& p,
                           float max_distance = std::numeric_limits<float>::infinity());
/// Every triangle that intersects the box, as sorted, unique primitive ids, into `out`.
void triangles_in_box(const GridView& grid, const format::Float3& lo, const format::Float3& hi,
                      std::vector<std::uint32_t>& out);
void triangles_in_box(const NestedGridView& grid, const format::Float3& lo,
                      const format::Float3& hi, std::vector<std::uint32_t>& out);
/// Inside/outside by a majority of five ray-parity votes (meaningful for closed meshes).
bool point_inside(const GridView& grid, const format::Float3& p);
bool point_inside(const NestedGridView& grid, const format::Float3& p);

}  // namespace kiln
