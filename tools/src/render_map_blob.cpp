// `kiln render` on a 2D blob: the layer, the index the mode needs, the map, the PNG and a
// summary (the drawing itself is render_map.cpp).
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "kiln/runtime/atomic_file.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/tools/render_map.hpp"
#include "kiln/tools/structure_choice.hpp"

namespace kiln::render {

namespace {

// `text` as a JSON string's contents: quotes, backslashes and control characters escaped.
std::string json_escaped(const std::string& text) {
  std::string out;
  for (const char c : text) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char code[8];
      std::snprintf(code, sizeof code, "\\u%04x", unsigned(c));
      out += code;
    } else {
      out += c;
    }
  }
  return out;
}

// One line on stdout: the image, the mode, the index and the costs (JSON with --json).
void print_summary(const std::string& out, const std::string& name, const std::string& index,
                   const Image& image, const MapStats& stats, bool json) {
  char numbers[256];
  if (json) {
    std::snprintf(numbers, sizeof numbers,
                  "\"width\":%u,\"height\":%u,\"cells\":%llu,\"mean_cost\":%.6g,\"max_cost\":%u,"
                  "\"heat_scale\":%u}",
                  image.width, image.height, (unsigned long long)stats.cells, stats.mean_cost,
                  stats.max_cost, stats.heat_scale);
    std::cout << "{\"image\":\"" << json_escaped(out) << "\",\"mode\":\"" << name
              << "\",\"structure\":\"" << json_escaped(index) << "\"," << numbers << "\n";
    return;
  }
  std::snprintf(numbers, sizeof numbers, " %ux%u, --mode %s", image.width, image.height,
                name.c_str());
  std::cout << "kiln render: " << out << numbers << (index.empty() ? "" : ", index ") << index;
  std::snprintf(numbers, sizeof numbers, ", %llu cells, mean cost %.2f",
                (unsigned long long)stats.cells, stats.mean_cost);
  std::cout << numbers << "\n";
}

}  // namespace

bool is_map_blob(const Blob& blob) {
  return blob.input().kind == InputKind::kPolygons2 || blob.input().kind == InputKind::kPoint2;
}

int render_map_command(const Blob& blob, const std::string& out, const std::string& accel,
                       const std::string& mode_name, const std::string& size_text, unsigned threads,
                       bool json) {
  auto fail = [](const std::string& message) {
    std::cerr << "kiln render: " << message << "\n";
    return 1;
  };
  std::error_code ec;
  if (std::filesystem::exists(out, ec) && std::filesystem::equivalent(blob.name(), out, ec))
    return fail("output " + out + " is the blob itself");
  const std::string name = mode_name.empty() ? "map" : mode_name;
  const auto mode = parse_map_mode(name);
  if (!mode) return fail("--mode '" + name + "' must be map, cells or heatmap for a 2D blob");
  std::string error;
  const auto size = parse_size(size_text, error);
  if (!size) return fail(error);
  const bool polygons = blob.input().kind == InputKind::kPolygons2;
  PolygonLayerView layer;
  PointTableView table;
  MapContent content;
  if (polygons)
    content.polygons = &(layer = blob.polygon_layer());
  else
    content.points = &(table = blob.point_table());
  ChosenStructure index;
  if (*mode != MapMode::kPlain || !accel.empty()) {
    index = polygons
                ? choose_structure(blob, accel, &StructureView::polygons,
                                   "answer point-in-polygon queries")
                : choose_structure(blob, accel, &StructureView::points2, "answer 2D point queries");
    content.polygon_index = index.view->polygons();
    content.point_index = polygons ? nullptr : index.view->points2();
  }
  MapStats stats;
  const Image image = draw_map(content, *mode, *size, threads, &stats);
  write_file_atomically(out, encode_png(image));
  print_summary(out, name, index.name, image, stats, json);
  return 0;
}

}  // namespace kiln::render
