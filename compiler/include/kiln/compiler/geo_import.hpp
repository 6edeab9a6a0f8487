// The 2D inputs of `kiln build`: GeoJSON (polygons or points) and CSV point tables, read into the
// in-memory PolygonLayer / PointTable2 (geo_layer.hpp). Errors are one line, "path: feature N
// (id X): what" or "path:LINE: what", thrown as ImportError.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "kiln/compiler/geo_layer.hpp"
#include "kiln/compiler/import.hpp"

namespace kiln {

/// How a 2D input is read (`kiln build --name-property, --lon-column/--x-column,
/// --lat-column/--y-column, --skip-invalid`). Each changes the blob, so each enters the build
/// cache key.
struct GeoImportOptions {
  std::string name_property = "name";  ///< the GeoJSON property kept as each feature's name
  std::string x_column;                ///< a CSV table's x (longitude) column
  std::string y_column;                ///< a CSV table's y (latitude) column
  /// Drop a broken feature (GeoJSON) or row (CSV) with a count instead of refusing the file; it
  /// stays as an empty feature so indices remain the source's.
  bool skip_invalid = false;

  bool operator==(const GeoImportOptions&) const = default;
};

/// What one 2D input holds: exactly one of `polygons` and `points`.
struct GeoInput {
  SourceFile source;  ///< the file read (import_geo_file; empty from the in-memory readers)
  std::optional<PolygonLayer> polygons;
  std::optional<PointTable2> points;
  /// Features whose geometry is null: kept as empty features (RFC 7946 allows them), counted.
  std::uint64_t null_geometries = 0;
  /// Rings with fewer than 3 distinct points (zero area, e.g. slivers a simplification left):
  /// dropped, a polygon with its holes when its outer ring is one. Counted.
  std::uint64_t degenerate_rings_dropped = 0;
};

/// The most nested arrays and objects a GeoJSON input may hold (a MultiPolygon feature in a
/// collection needs 8): deeper input is refused before it costs memory.
inline constexpr std::size_t kGeoJsonMaxDepth = 64;

/// Whether `name` (a path, after any `.zst`) is read as a 2D input: .geojson, .json or .csv,
/// any case.
bool is_geo_input_name(std::string_view name);
bool is_csv_input_name(std::string_view name);

/// Folds `--lon-column/--lat-column` (geographic names) into `options.x_column/y_column` and
/// checks them against the inputs: throws std::invalid_argument when a pair differs or when
/// columns are named but no input is CSV. kiln build and the Python module's build share it.
void resolve_point_columns(GeoImportOptions& options, const std::string& lon_column,
                           const std::string& lat_column, std::span<const std::string> inputs);

/// A GeoJSON FeatureCollection, Feature or bare geometry: Polygon / MultiPolygon (with holes)
/// make a polygon layer, Point / MultiPoint a point table; a file mixing both is refused.
/// Throws ImportError.
GeoInput import_geojson(const std::string& path, std::string_view text,
                        const GeoImportOptions& options);

/// A CSV table with a header row; `options.x_column` / `y_column` name the coordinates (both
/// required). Other columns are not stored. Throws ImportError.
PointTable2 import_csv_points(const std::string& path, std::string_view text,
                              const GeoImportOptions& options);

/// Reads `path` (a trailing .zst inflated within `limits`) and picks the reader by the inner
/// name's extension. Throws ImportError.
GeoInput import_geo_file(const std::string& path, const GeoImportOptions& options,
                         const ImportLimits& limits = {});

}  // namespace kiln
