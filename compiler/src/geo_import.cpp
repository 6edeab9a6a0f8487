// Which inputs are 2D, and reading one from its path (a trailing .zst inflated first).
#include <algorithm>
#include <cctype>
#include <string>

#include "kiln/compiler/geo_import.hpp"

namespace kiln {
namespace {

bool ends_with_nocase(std::string_view name, std::string_view suffix) {
  if (name.size() < suffix.size()) return false;
  return std::equal(suffix.begin(), suffix.end(), name.end() - suffix.size(),
                    [](char lower, char c) { return std::tolower((unsigned char)c) == lower; });
}

std::string_view without_zst(std::string_view name) {
  return ends_with_nocase(name, ".zst") ? name.substr(0, name.size() - 4) : name;
}

}  // namespace

bool is_csv_input_name(std::string_view name) {
  return ends_with_nocase(without_zst(name), ".csv");
}

bool is_geo_input_name(std::string_view name) {
  const std::string_view inner = without_zst(name);
  return ends_with_nocase(inner, ".geojson") || ends_with_nocase(inner, ".json") ||
         ends_with_nocase(inner, ".csv");
}

GeoInput import_geo_file(const std::string& path, const GeoImportOptions& options,
                         const ImportLimits& limits) {
  const InputBytes input = read_input_bytes(path, limits);
  const std::string_view text(reinterpret_cast<const char*>(input.bytes.data()),
                              input.bytes.size());
  // Errors name the path as given (with its .zst), as the mesh importers' do.
  GeoInput out;
  try {
    if (is_csv_input_name(path))
      out.points = import_csv_points(path, text, options);
    else
      out = import_geojson(path, text, options);
  } catch (const std::bad_alloc&) {
    throw ImportError(path + ": out of memory while reading");
  }
  out.source = input.source;
  return out;
}

}  // namespace kiln
