// The 2D inputs of a blob as spans over its sections: a polygon layer or a point table
// (docs/FORMAT.md, "2D inputs"). Blob::open checks every offset array (starts at 0,
// non-decreasing, ends at the count it indexes) and every ring's size (at least 3), so a view
// may index with them freely; coordinates may be anything (kiln verify checks they are finite).
#pragma once

#include <cstdint>
#include <span>
#include <string_view>

#include "kiln/formats/vector.hpp"

namespace kiln {

/// A column of strings, one per feature: offsets (size() + 1) into bytes.
struct StringTableView {
  std::span<const std::uint64_t> offsets;
  std::span<const char> bytes;

  std::size_t size() const { return offsets.empty() ? 0 : offsets.size() - 1; }
  bool empty() const { return size() == 0; }
  std::string_view operator[](std::size_t i) const {
    return {bytes.data() + offsets[i], std::size_t(offsets[i + 1] - offsets[i])};
  }
};

/// A polygon layer: a feature owns polygons `feature_polygons[f] .. [f+1]`; a polygon owns
/// rings `polygon_rings[p] .. [p+1]`, the first the outer ring and the others holes; a ring
/// owns vertices `ring_vertices[r] .. [r+1]` (at least 3, the closing vertex not repeated).
/// A feature dropped by --skip-invalid has no polygon, so indices are the source's.
struct PolygonLayerView {
  std::span<const format::Double2> vertices;
  std::span<const std::uint64_t> ring_vertices;
  std::span<const std::uint64_t> polygon_rings;
  std::span<const std::uint64_t> feature_polygons;
  StringTableView ids;    ///< one per feature
  StringTableView names;  ///< one per feature
  std::string_view name_property;
  std::uint64_t features_skipped = 0;
  format::Box2d bounds;

  std::size_t feature_count() const { return feature_polygons.size() - 1; }
  std::size_t polygon_count() const { return polygon_rings.size() - 1; }
  std::size_t ring_count() const { return ring_vertices.size() - 1; }
  std::span<const format::Double2> ring(std::size_t r) const {
    return vertices.subspan(ring_vertices[r], ring_vertices[r + 1] - ring_vertices[r]);
  }
};

/// A 2D point table: point i is feature (row) i when `feature_points` is empty; else feature
/// f owns points `feature_points[f] .. [f+1]`.
struct PointTableView {
  std::span<const format::Double2> points;
  std::span<const std::uint64_t> feature_points;
  StringTableView ids;    ///< one per feature, or empty
  StringTableView names;  ///< one per feature, or empty
  std::string_view x_column, y_column, name_property;
  std::uint64_t rows_skipped = 0;
  format::Box2d bounds;

  std::size_t feature_count() const {
    return feature_points.empty() ? points.size() : feature_points.size() - 1;
  }
};

}  // namespace kiln
