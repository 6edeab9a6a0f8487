// What the importer fuzzers do with an input, shared with the regression test: import the bytes
// as a file of the target's extension (companion files never read), then assemble the scene, as
// `kiln build` would. An ImportError is the expected answer to bad bytes; any other exception, a
// crash or a sanitizer report is a finding.
#pragma once

#include <cmath>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "kiln/compiler/geo_import.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/compiler/scene.hpp"

namespace kiln::fuzz {

/// The limits the importer fuzzers run under: small enough that a bomb is refused well inside
/// libFuzzer's memory limit (-rss_limit_mb=2048), as `kiln build` refuses it inside its own.
inline ImportLimits fuzz_import_limits() {
  ImportLimits limits;
  limits.max_inflated_bytes = std::uint64_t{64} << 20;
  return limits;
}

/// Offsets as geo_layer.hpp promises them (from 0, non-decreasing, ending at `size`), else
/// std::logic_error: a reader bug, which the fuzzers report.
inline void check_offsets(const std::vector<std::uint64_t>& offsets, std::uint64_t size,
                          std::uint64_t min_step = 0) {
  if (offsets.empty() || offsets.front() != 0 || offsets.back() != size)
    throw std::logic_error("offsets do not span their array");
  for (std::size_t i = 1; i < offsets.size(); ++i)
    if (offsets[i] < offsets[i - 1] + min_step) throw std::logic_error("offsets decrease");
}

/// What the 2D readers promise of what they return (geo_layer.hpp), else std::logic_error.
inline void check_geo(const GeoInput& in) {
  if (in.polygons.has_value() == in.points.has_value())
    throw std::logic_error("a 2D input is polygons or points");
  if (in.polygons) {
    const PolygonLayer& l = *in.polygons;
    check_offsets(l.ring_vertices, l.vertices.size(), 3);  // every ring at least 3 vertices
    check_offsets(l.polygon_rings, l.ring_count(), 1);     // every polygon an outer ring
    check_offsets(l.feature_polygons, l.polygon_count());
    if (l.ids.size() != l.feature_count() || l.names.size() != l.feature_count())
      throw std::logic_error("one id and name per feature");
    for (const auto& v : l.vertices)
      if (!std::isfinite(v.x) || !std::isfinite(v.y) || !l.bounds.contains(v))
        throw std::logic_error("a vertex not finite or outside the bounds");
  } else {
    const PointTable2& t = *in.points;
    if (!t.feature_points.empty()) check_offsets(t.feature_points, t.points.size());
    if (t.ids.size() != t.names.size() || (t.ids.size() != 0 && t.ids.size() != t.feature_count()))
      throw std::logic_error("one id and name per feature");
    for (const auto& p : t.points)
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !t.bounds.contains(p))
        throw std::logic_error("a point not finite or outside the bounds");
  }
}

/// The 2D readers (".geojson", ".csv" with columns "x" and "y"): strict, then with
/// --skip-invalid (which must accept whatever the strict read accepted); what they return is
/// checked (check_geo).
inline void import_geo(const std::string& path, std::span<const std::byte> bytes) {
  const std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  for (const bool skip : {false, true}) {
    GeoImportOptions options;
    options.x_column = "x", options.y_column = "y", options.skip_invalid = skip;
    try {
      GeoInput in;
      if (is_csv_input_name(path))
        in.points = import_csv_points(path, text, options);
      else
        in = import_geojson(path, text, options);
      check_geo(in);
    } catch (const ImportError&) {
      if (skip) throw;
      continue;
    }
    return;  // the strict read passed: so would the lenient one
  }
}

/// Imports `bytes` as "fuzz" + `extension` (e.g. ".obj", ".ply.zst") and assembles the scene.
/// Returns the refusal (one line), or empty when the input imported.
inline std::string import_and_assemble(const std::string& extension,
                                       std::span<const std::byte> bytes) {
  // A directory that does not exist: a glTF's relative buffer URIs find nothing.
  const std::string path = "/nonexistent-kiln-fuzz/fuzz" + extension;
  try {
    if (is_geo_input_name(path)) {
      import_geo(path, bytes);
      return "";
    }
    std::vector<ImportedFile> files;
    files.push_back(import_bytes(path, bytes, fuzz_import_limits(), false));
    const Scene scene = assemble_scene(std::move(files));
    return scene.triangles.empty() && scene.positions.empty() ? "empty scene" : "";
  } catch (const ImportError& e) {
    const std::string message = e.what();
    if (message.find('\n') != std::string::npos) throw std::logic_error("two-line refusal");
    return message;
  }
}

}  // namespace kiln::fuzz
