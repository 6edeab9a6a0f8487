// The StructureView of a triangle structure: ray casting (16-byte Hit records, the triangle's
// geometric normal as the surface normal) and the surface queries, over any concrete view V
// that is a RayStructure with HitType Hit and has the free functions closest_point(V, ...),
// point_inside(V, ...) and triangles_in_box(V, ...). The concrete view's calls stay direct: the
// one virtual call is the capability's, per query or per batch.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "kiln/formats/geometry.hpp"
#include "kiln/formats/ray_triangle.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/capabilities.hpp"
#include "kiln/runtime/ray_structure.hpp"

namespace kiln {

/// verify: a structure's copy of every triangle's corners (`copies`, by triangle id, in section
/// `section`) equals the scene's, bit for bit.
inline void verify_triangle_copies(const Blob& blob, std::uint32_t section, const std::string& name,
                                   std::span<const format::RayTriangle> copies) {
  const auto positions = blob.positions();
  const auto triangles = blob.triangles();
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    const auto& t = triangles[i];
    const format::RayTriangle expected{positions[t.v[0]], positions[t.v[1]], positions[t.v[2]]};
    if (std::memcmp(&expected, &copies[i], sizeof(expected)) != 0)
      blob.fail_section(
          section, name + " triangle " + std::to_string(i) + " does not match the scene's corners");
  }
}

/// verify: every triangle of the scene is among `prim_ids` (section `section`), i.e. in a leaf.
inline void verify_every_triangle_listed(const Blob& blob, std::uint32_t section,
                                         const std::string& name,
                                         std::span<const std::uint32_t> prim_ids) {
  std::vector<bool> listed(blob.triangles().size());
  for (const auto id : prim_ids) listed[id] = true;
  for (std::size_t i = 0; i < listed.size(); ++i)
    if (!listed[i])
      blob.fail_section(section, name + " triangle " + std::to_string(i) + " is in no leaf");
}

/// The geometric normal (b - a) x (c - a) of triangle `prim`, not normalised; zero when the
/// triangle or one of its vertices is out of range.
inline format::Float3 triangle_normal(std::span<const format::Triangle> triangles,
                                      std::span<const format::Float3> positions,
                                      std::uint32_t prim) {
  if (prim >= triangles.size()) return {0, 0, 0};
  const auto& tri = triangles[prim];
  for (const auto v : tri.v)
    if (v >= positions.size()) return {0, 0, 0};
  const auto& a = positions[tri.v[0]];
  const auto& b = positions[tri.v[1]];
  const auto& c = positions[tri.v[2]];
  const float e1[3] = {b.x - a.x, b.y - a.y, b.z - a.z};
  const float e2[3] = {c.x - a.x, c.y - a.y, c.z - a.z};
  return {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
          e1[0] * e2[1] - e1[1] * e2[0]};
}

namespace triangle_structure_detail {

// Unqualified calls, so the concrete view's overloads are found by argument-dependent lookup
// (inside the adapter the capability's member functions of the same names would hide them).
template <class V>
ClosestPoint closest(const V& view, const format::Float3& p, float max_distance) {
  return closest_point(view, p, max_distance);
}
template <class V>
bool inside(const V& view, const format::Float3& p) {
  return point_inside(view, p);
}
template <class V>
void in_box(const V& view, const format::Float3& lo, const format::Float3& hi,
            std::vector<std::uint32_t>& out) {
  triangles_in_box(view, lo, hi, out);
}

}  // namespace triangle_structure_detail

template <RayStructure V>
class TriangleStructure final : public StructureView, public RayQueries, public SurfaceQueries {
 public:
  /// Borrows `blob` (its triangles and positions give the hit normals).
  TriangleStructure(const Blob& blob, V view)
      : view_(std::move(view)), triangles_(blob.triangles()), positions_(blob.positions()) {}

  const RayQueries* rays() const override { return this; }
  const SurfaceQueries* surface() const override { return this; }

  std::size_t record_size() const override { return sizeof(Hit); }
  void trace_records(std::span<const Ray> rays, std::span<std::byte> records, bool any_hit,
                     unsigned threads) const override {
    const std::span<Hit> hits(reinterpret_cast<Hit*>(records.data()), rays.size());
    trace_rays(view_, rays, hits, any_hit, threads);
  }
  Hit closest(const Ray& ray) const override { return view_.intersect(ray); }
  SurfaceHit intersect_counting(const Ray& ray, Cost& cost) const override {
    SurfaceHit surface{view_.intersect_counting(ray, cost)};
    if (surface.hit.hit())
      surface.normal = triangle_normal(triangles_, positions_, surface.hit.prim);
    return surface;
  }

  ClosestPoint closest_point(const format::Float3& p, float max_distance) const override {
    return triangle_structure_detail::closest(view_, p, max_distance);
  }
  bool inside(const format::Float3& p) const override {
    return triangle_structure_detail::inside(view_, p);
  }
  void triangles_in_box(const format::Float3& lo, const format::Float3& hi,
                        std::vector<std::uint32_t>& out) const override {
    triangle_structure_detail::in_box(view_, lo, hi, out);
  }

 private:
  V view_;
  std::span<const format::Triangle> triangles_;
  std::span<const format::Float3> positions_;
};

}  // namespace kiln
