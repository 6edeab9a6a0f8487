// The work of the blob fuzzers on one input, shared by the harness (tests/fuzz/blob_fuzzer.cpp)
// and the regression test over tests/fuzz/regressions/ (tests/fuzz_regression_test.cpp).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <iterator>
#include <span>
#include <string>
#include <vector>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/capabilities.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/structure_registry.hpp"

namespace kiln::fuzz {

using format::Float3;

inline bool finite(const Float3& p) {
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
}

// The input's bounds as a usable box: a fuzzed manifest may hold anything, and the queries a
// program asks are its own business, so keep them finite and of sane magnitude.
inline void query_box(const Blob& blob, Float3& lo, Float3& hi) {
  lo = blob.input().bounds.min;
  hi = blob.input().bounds.max;
  const bool sane = finite(lo) && finite(hi) && lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z &&
                    std::fabs(lo.x) < 1e6f && std::fabs(lo.y) < 1e6f && std::fabs(lo.z) < 1e6f &&
                    std::fabs(hi.x) < 1e6f && std::fabs(hi.y) < 1e6f && std::fabs(hi.z) < 1e6f;
  if (!sane) {
    lo = {-1, -1, -1};
    hi = {1, 1, 1};
  }
}

// The 2D capabilities (point in polygon, point ranges and neighbours) over the x, y of the box.
inline void exercise_2d(const StructureView& view, const Float3& lo, const Float3& hi) {
  using format::Double2;
  const Double2 a{lo.x, lo.y}, b{hi.x, hi.y}, c{(a.x + b.x) * 0.5, (a.y + b.y) * 0.5};
  const Double2 points[] = {c, a, b, {b.x + 1, a.y - 1}, {a.x, c.y}};
  const format::Box2d box{a, c}, all{{a.x - 1, a.y - 1}, {b.x + 1, b.y + 1}};
  std::vector<std::uint32_t> ids;
  std::vector<IndexCell2> cells;
  if (const PolygonQueries* polygons = view.polygons()) {
    for (const Double2& p : points) {
      (void)polygons->locate(p);
      Cost cost;
      (void)polygons->locate_counting(p, cost);
      polygons->locate_all(p, ids);
    }
    std::uint32_t found[std::size(points)];
    polygons->locate_many(points, found, 1);
    polygons->features_in_box(box, ids);
    polygons->features_in_box(all, ids);
    polygons->features_in_box({b, a}, ids);  // an empty (inverted) box
    polygons->cells(cells);
  }
  if (const Point2Queries* points2 = view.points2()) {
    Neighbor2 found[4];
    std::vector<Neighbor2> within;
    for (const Double2& p : points) {
      (void)points2->nearest(p, found);
      points2->within_radius(p, (b.x - a.x + b.y - a.y) * 0.25, within);
    }
    points2->range(box, ids);
    Cost cost;
    points2->range_counting(all, ids, cost);
    points2->range({b, a}, ids);
    points2->cells(cells);
  }
}

inline void exercise(const StructureView& view, const Float3& lo, const Float3& hi) {
  const Float3 c{(lo.x + hi.x) * 0.5f, (lo.y + hi.y) * 0.5f, (lo.z + hi.z) * 0.5f};
  const Float3 ext{hi.x - lo.x + 1e-3f, hi.y - lo.y + 1e-3f, hi.z - lo.z + 1e-3f};
  const float diag = std::sqrt(ext.x * ext.x + ext.y * ext.y + ext.z * ext.z);

  if (const RayQueries* rays = view.rays()) {
    // Axis rays into the box from outside, a diagonal, one from the centre, one that misses.
    std::vector<Ray> batch;
    const float inf = INFINITY;
    batch.push_back({{lo.x - ext.x, c.y, c.z}, 0.0f, {1, 0, 0}, inf});
    batch.push_back({{c.x, hi.y + ext.y, c.z}, 0.0f, {0, -1, 0}, inf});
    batch.push_back({{c.x, c.y, lo.z - ext.z}, 0.0f, {0, 0, 1}, inf});
    batch.push_back({{lo.x - ext.x, lo.y - ext.y, lo.z - ext.z}, 0.0f, {ext.x, ext.y, ext.z}, inf});
    batch.push_back({c, 0.0f, {0.3f, -0.5f, 0.81f}, inf});
    batch.push_back({{hi.x + ext.x, hi.y + ext.y, hi.z + ext.z}, 0.0f, {1, 1, 1}, inf});
    batch.push_back({{lo.x, c.y + 0.1f * ext.y, c.z}, 0.0f, {1, 0.01f, 0}, diag * 0.5f});

    const std::size_t record = rays->record_size();
    std::vector<std::uint64_t> storage((batch.size() * record + 7) / 8 + 1);
    std::span<std::byte> records(reinterpret_cast<std::byte*>(storage.data()),
                                 batch.size() * record);
    rays->trace_records(batch, records, false, 1);
    rays->trace_records(batch, records, true, 1);
    for (const Ray& ray : batch) {
      (void)rays->closest(ray);
      Cost cost;
      (void)rays->intersect_counting(ray, cost);
    }
  }

  const Float3 points[] = {c, lo, hi, {hi.x + ext.x, lo.y - ext.y, c.z}};
  if (const SurfaceQueries* surface = view.surface()) {
    for (const Float3& p : points) {
      (void)surface->closest_point(p, INFINITY);
      (void)surface->closest_point(p, diag * 0.1f);
      (void)surface->inside(p);
    }
    std::vector<std::uint32_t> ids;
    surface->triangles_in_box(lo, c, ids);
    surface->triangles_in_box(hi, lo, ids);  // an empty (inverted) box
  }
  if (const NeighborQueries* neighbors = view.neighbors()) {
    Neighbor found[4];
    std::vector<Neighbor> within;
    for (const Float3& p : points) {
      (void)neighbors->nearest(p, found);
      neighbors->within_radius(p, diag * 0.25f, within);
    }
    (void)neighbors->nearest(c, std::span<Neighbor>(found, 0));
  }
  if (const OccupancyQueries* occupancy = view.occupancy()) {
    for (const Float3& p : points) (void)occupancy->occupied(p);
  }
  exercise_2d(view, lo, hi);
}

// What a program reads besides the structures (kiln dump's header, sources, meshes and input);
// the first and last element of each input span, so ASan sees them in bounds.
template <class T>
void touch(std::span<const T> span) {
  if (span.empty()) return;
  volatile unsigned char sink = *reinterpret_cast<const unsigned char*>(&span.front());
  sink = *reinterpret_cast<const unsigned char*>(&span.back());
  (void)sink;
}

inline void read_metadata(const Blob& blob) {
  (void)blob.tool_name();
  (void)blob.tool_version();
  (void)blob.options();
  (void)blob.sources();
  const std::size_t meshes = blob.mesh_count();
  for (std::size_t i = 0; i < meshes && i < 4; ++i) (void)blob.mesh(i);
  if (meshes > 4) (void)blob.mesh(meshes - 1);
  touch(blob.positions());
  touch(blob.normals());
  touch(blob.triangles());
  touch(blob.triangle_mesh_ids());
  if (blob.input().kind == InputKind::kPolygons2) {
    const PolygonLayerView layer = blob.polygon_layer();
    touch(layer.vertices);
    if (layer.ring_count() > 0) touch(layer.ring(layer.ring_count() - 1));
    if (layer.feature_count() > 0)
      (void)layer.ids[layer.feature_count() - 1], (void)layer.names[layer.feature_count() - 1];
  } else if (blob.input().kind == InputKind::kPoint2) {
    const PointTableView table = blob.point_table();
    touch(table.points);
    touch(table.feature_points);
    if (!table.names.empty()) (void)table.names[table.names.size() - 1];
  }
}

/// What blob_fuzzer does with one input: open the bytes (64-byte aligned) as a blob, read its
/// metadata, describe and open every structure and ask each capability a few bounded queries,
/// then verify. Returns "" when the
/// blob was accepted, else the first refusal (a BlobError's message); a structure that refuses
/// to open is skipped (its message goes to `refusals`). Anything else (another exception, a
/// crash, a sanitizer report) is a bug.
inline std::string open_query_verify(std::span<const std::byte> bytes,
                                     std::vector<std::string>* refusals = nullptr) {
  try {
    const Blob blob = Blob::open_memory(bytes, "<fuzz>");
    read_metadata(blob);
    Float3 lo, hi;
    query_box(blob, lo, hi);
    for (const StructureInfo& info : blob.structures()) {
      try {
        // What `kiln dump` prints, on a blob that was opened but not verified.
        if (const StructureKind* kind = find_structure_kind(info.kind))
          (void)kind->describe(blob, info);
      } catch (const BlobError& e) {
        if (refusals) refusals->push_back(info.name + " (describe): " + e.what());
      }
      try {
        const auto view = open_structure(blob, info.name);
        if (view) exercise(*view, lo, hi);
      } catch (const BlobError& e) {
        if (refusals) refusals->push_back(info.name + ": " + e.what());
      }
    }
    blob.verify();
    return {};
  } catch (const BlobError& e) {
    return e.what();
  }
}

}  // namespace kiln::fuzz
