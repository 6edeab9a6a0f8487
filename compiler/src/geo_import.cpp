// Which inputs are 2D, and reading one from its path (a trailing .zst inflated first).
#include <algorithm>
#include <cctype>
#include <stdexcept>
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

void resolve_point_columns(GeoImportOptions& options, const std::string& lon_column,
                           const std::string& lat_column, std::span<const std::string> inputs) {
  const auto fold = [](std::string& xy, const std::string& lonlat, const char* flags) {
    if (lonlat.empty()) return;
    if (!xy.empty() && xy != lonlat) throw std::invalid_argument(std::string(flags) + " differ");
    xy = lonlat;
  };
  fold(options.x_column, lon_column, "--lon-column and --x-column");
  fold(options.y_column, lat_column, "--lat-column and --y-column");
  const bool csv = std::any_of(inputs.begin(), inputs.end(),
                               [](const std::string& input) { return is_csv_input_name(input); });
  if (!csv && (!options.x_column.empty() || !options.y_column.empty()))
    throw std::invalid_argument(
        "--lon-column/--lat-column (--x-column/--y-column) apply to a CSV input only");
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
