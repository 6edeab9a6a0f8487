// What the importer fuzzers do with an input, shared with the regression test: import the bytes
// as a file of the target's extension (companion files never read), then assemble the scene, as
// `kiln build` would. An ImportError is the expected answer to bad bytes; any other exception, a
// crash or a sanitizer report is a finding.
#pragma once

#include <cstdint>
#include <span>
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

/// The 2D readers (".geojson", ".csv" with columns "x" and "y"): strict, then with
/// --skip-invalid (which must accept whatever the strict read accepted).
inline void import_geo(const std::string& path, std::span<const std::byte> bytes) {
  const std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  for (const bool skip : {false, true}) {
    GeoImportOptions options;
    options.x_column = "x", options.y_column = "y", options.skip_invalid = skip;
    try {
      if (is_csv_input_name(path))
        (void)import_csv_points(path, text, options);
      else
        (void)import_geojson(path, text, options);
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
