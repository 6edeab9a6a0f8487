// The 2D inputs in memory, as the GeoJSON and CSV readers produce them and the 2D builders
// consume them: a polygon layer (features -> polygons -> rings -> vertices) or a point table.
// Written into the blob as the manifest's PolygonLayer / PointTable input (docs/FORMAT.md).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "kiln/formats/vector.hpp"

namespace kiln {

/// A column of strings, one per feature: `offsets` has size() + 1 entries into `bytes`.
struct StringColumn {
  std::vector<std::uint64_t> offsets{0};
  std::string bytes;

  std::size_t size() const { return offsets.size() - 1; }
  void push(std::string_view text) {
    bytes.append(text);
    offsets.push_back(bytes.size());
  }
  std::string_view operator[](std::size_t i) const {
    return std::string_view(bytes).substr(offsets[i], offsets[i + 1] - offsets[i]);
  }
};

/// A polygon layer. A feature (a GeoJSON Polygon or MultiPolygon) owns a range of polygons; a
/// polygon owns a range of rings, the first its outer ring and the others its holes; a ring owns
/// a range of vertices, stored once (without repeating the first at the end), at least 3.
/// A feature dropped by --skip-invalid stays as an empty range, so feature indices are always
/// those of the source. Orientation is kept as read: queries never depend on it.
struct PolygonLayer {
  std::vector<format::Double2> vertices;
  std::vector<std::uint64_t> ring_vertices{0};     ///< ring_count + 1 offsets into vertices
  std::vector<std::uint64_t> polygon_rings{0};     ///< polygon_count + 1 offsets into rings
  std::vector<std::uint64_t> feature_polygons{0};  ///< feature_count + 1 offsets into polygons
  StringColumn ids;    ///< each feature's `id` as text ("" when it has none)
  StringColumn names;  ///< each feature's `name_property` as text ("" when absent)
  std::string name_property = "name";
  std::uint64_t features_skipped = 0;  ///< by --skip-invalid (empty ranges)
  std::string first_skipped;           ///< why the first feature it dropped was refused
  format::Box2d bounds;                ///< over every vertex (empty when none)

  std::size_t feature_count() const { return feature_polygons.size() - 1; }
  std::size_t polygon_count() const { return polygon_rings.size() - 1; }
  std::size_t ring_count() const { return ring_vertices.size() - 1; }
};

/// A 2D point table: one point per CSV row, or the points of GeoJSON Point / MultiPoint
/// features. `feature_points` is empty when point i is feature (row) i; else it has
/// feature_count + 1 offsets into `points`. Rows and features dropped by --skip-invalid keep
/// their index (an empty range; a CSV table with a dropped row therefore has `feature_points`).
struct PointTable2 {
  std::vector<format::Double2> points;
  std::vector<std::uint64_t> feature_points;  ///< empty, or feature_count + 1 offsets
  StringColumn ids;                           ///< per feature, or empty (a CSV table)
  StringColumn names;                         ///< per feature, or empty (a CSV table)
  std::string x_column, y_column;             ///< a CSV table's coordinate columns ("" for GeoJSON)
  std::string name_property;                  ///< a GeoJSON table's name property ("" for CSV)
  std::uint64_t rows_skipped = 0;             ///< by --skip-invalid
  std::string first_skipped;                  ///< why the first row it dropped was refused
  format::Box2d bounds;                       ///< over every point (empty when none)

  std::size_t feature_count() const {
    return feature_points.empty() ? points.size() : feature_points.size() - 1;
  }
};

}  // namespace kiln
