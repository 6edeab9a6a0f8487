// The 2D inputs (a polygon layer, a point table): checks at open, so that views may index with
// every offset freely, the spans over them, and kiln verify's finite coordinates.
#include <cmath>
#include <string>

#include "kiln/formats/section_kinds.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/manifest.hpp"

namespace kiln {

namespace {

format::Box2d to_box(const schema::Bounds2d* b) {
  if (b == nullptr) return {};
  return {{b->min().x(), b->min().y()}, {b->max().x(), b->max().y()}};
}

format::Box3f to_box3(const format::Box2d& b) {
  if (b.empty()) return {{0, 0, 0}, {0, 0, 0}};
  return {{float(b.min.x), float(b.min.y), 0}, {float(b.max.x), float(b.max.y), 0}};
}

std::string_view text(const flatbuffers::String* s) {
  return s ? std::string_view(s->data(), s->size()) : std::string_view();
}

// An offsets array: starts at 0, each entry at least the previous plus `min_step`, ends at
// `end`. O(entries), a handful of microseconds for a counties layer.
void check_offsets(const Blob& blob, std::uint32_t section, const std::string& what,
                   std::uint64_t end, std::uint64_t min_step) {
  const auto offsets = blob.section_view<std::uint64_t>(section);
  if (offsets.empty() || offsets.front() != 0)
    blob.fail_section(section, what + " do not start at 0");
  for (std::size_t i = 1; i < offsets.size(); ++i)
    if (offsets[i] < offsets[i - 1] || offsets[i] - offsets[i - 1] < min_step)
      blob.fail_section(section, what + " " + std::to_string(i - 1) + " has " +
                                     std::to_string(offsets[i] - offsets[i - 1]) +
                                     " entries (at least " + std::to_string(min_step) + ")");
  if (offsets.back() != end)
    blob.fail_section(section, what + " end at " + std::to_string(offsets.back()) + ", not " +
                                   std::to_string(end));
}

// A string column: count + 1 offsets into a byte section, both present or both absent.
void check_strings(const Blob& blob, const std::string& what, std::uint32_t offsets,
                   std::uint32_t bytes, std::uint64_t count, bool optional) {
  if (optional && offsets == kNoSection && bytes == kNoSection) return;
  blob.check_section(what + " offsets", offsets, format::kSectionStringOffsets,
                     sizeof(std::uint64_t), count + 1, false);
  const std::uint64_t size = bytes == kNoSection || bytes >= blob.sections().size()
                                 ? 0
                                 : blob.sections()[bytes].element_count;
  blob.check_section(what + " bytes", bytes, format::kSectionStringBytes, 1, size, false);
  check_offsets(blob, offsets, what + " strings", size, 0);
}

}  // namespace

void Blob::validate_polygon_layer() {
  const auto* found = manifest_of(*this).input_as_PolygonLayer();
  if (found == nullptr) fail_section(0, "manifest names a polygon layer input but holds none");
  const auto& layer = *found;
  const std::uint64_t features = layer.feature_count(), polygons = layer.polygon_count();
  const std::uint64_t rings = layer.ring_count(), vertices = layer.vertex_count();
  geo_ = {};
  geo_.vertices = layer.vertices(), geo_.ring_vertices = layer.ring_vertices();
  geo_.polygon_rings = layer.polygon_rings(), geo_.feature_polygons = layer.feature_polygons();
  check_section("layer vertices", geo_.vertices, format::kSectionLayerVertices,
                sizeof(format::Double2), vertices, false);
  check_section("ring offsets", geo_.ring_vertices, format::kSectionLayerRings,
                sizeof(std::uint64_t), rings + 1, false);
  check_section("polygon offsets", geo_.polygon_rings, format::kSectionLayerPolygons,
                sizeof(std::uint64_t), polygons + 1, false);
  check_section("feature offsets", geo_.feature_polygons, format::kSectionLayerFeatures,
                sizeof(std::uint64_t), features + 1, false);
  // Rings have at least 3 vertices, polygons an outer ring; features may be empty (skipped).
  check_offsets(*this, geo_.ring_vertices, "rings", vertices, 3);
  check_offsets(*this, geo_.polygon_rings, "polygons", rings, 1);
  check_offsets(*this, geo_.feature_polygons, "features", polygons, 0);
  geo_.id_offsets = layer.id_offsets(), geo_.id_bytes = layer.id_bytes();
  geo_.name_offsets = layer.name_offsets(), geo_.name_bytes = layer.name_bytes();
  check_strings(*this, "feature id", geo_.id_offsets, geo_.id_bytes, features, false);
  check_strings(*this, "feature name", geo_.name_offsets, geo_.name_bytes, features, false);
  input_ = {};
  input_.kind = InputKind::kPolygons2;
  input_.vertex_count = vertices;
  input_.feature_count = features;
  input_.bounds2 = to_box(layer.bounds());
  input_.bounds = to_box3(input_.bounds2);
}

void Blob::validate_point_table() {
  const auto* found = manifest_of(*this).input_as_PointTable();
  if (found == nullptr) fail_section(0, "manifest names a point table input but holds none");
  const auto& table = *found;
  const std::uint64_t points = table.point_count(), features = table.feature_count();
  geo_ = {};
  geo_.points = table.points(), geo_.feature_points = table.feature_points();
  check_section("points", geo_.points, format::kSectionPoints2, sizeof(format::Double2), points,
                false);
  if (geo_.feature_points == kNoSection) {
    if (features != points)
      fail_section(0, "point table has " + std::to_string(features) + " rows for " +
                          std::to_string(points) + " points and no row offsets");
  } else {
    check_section("row offsets", geo_.feature_points, format::kSectionPointFeatures,
                  sizeof(std::uint64_t), features + 1, false);
    check_offsets(*this, geo_.feature_points, "rows", points, 0);
  }
  geo_.id_offsets = table.id_offsets(), geo_.id_bytes = table.id_bytes();
  geo_.name_offsets = table.name_offsets(), geo_.name_bytes = table.name_bytes();
  check_strings(*this, "feature id", geo_.id_offsets, geo_.id_bytes, features, true);
  check_strings(*this, "feature name", geo_.name_offsets, geo_.name_bytes, features, true);
  input_ = {};
  input_.kind = InputKind::kPoint2;
  input_.vertex_count = points;
  input_.feature_count = features;
  input_.bounds2 = to_box(table.bounds());
  input_.bounds = to_box3(input_.bounds2);
}

PolygonLayerView Blob::polygon_layer() const {
  if (input_.kind != InputKind::kPolygons2) fail("is not built from a 2D polygon layer");
  const auto& layer = *manifest_of(*this).input_as_PolygonLayer();
  PolygonLayerView view;
  view.vertices = section_view<format::Double2>(geo_.vertices);
  view.ring_vertices = section_view<std::uint64_t>(geo_.ring_vertices);
  view.polygon_rings = section_view<std::uint64_t>(geo_.polygon_rings);
  view.feature_polygons = section_view<std::uint64_t>(geo_.feature_polygons);
  view.ids = {section_view<std::uint64_t>(geo_.id_offsets), section_view<char>(geo_.id_bytes)};
  view.names = {section_view<std::uint64_t>(geo_.name_offsets),
                section_view<char>(geo_.name_bytes)};
  view.name_property = text(layer.name_property());
  view.features_skipped = layer.features_skipped();
  view.bounds = input_.bounds2;
  return view;
}

PointTableView Blob::point_table() const {
  if (input_.kind != InputKind::kPoint2) fail("is not built from a 2D point table");
  const auto* found = manifest_of(*this).input_as_PointTable();
  if (found == nullptr) fail_section(0, "manifest names a point table input but holds none");
  const auto& table = *found;
  PointTableView view;
  view.points = section_view<format::Double2>(geo_.points);
  view.feature_points = section_view<std::uint64_t>(geo_.feature_points);
  view.ids = {section_view<std::uint64_t>(geo_.id_offsets), section_view<char>(geo_.id_bytes)};
  view.names = {section_view<std::uint64_t>(geo_.name_offsets),
                section_view<char>(geo_.name_bytes)};
  view.x_column = text(table.x_column());
  view.y_column = text(table.y_column());
  view.name_property = text(table.name_property());
  view.rows_skipped = table.rows_skipped();
  view.bounds = input_.bounds2;
  return view;
}

// Finite coordinates (open does not read them: O(vertices)).
void Blob::verify_geo_input() const {
  const std::uint32_t section = input_.kind == InputKind::kPolygons2 ? geo_.vertices : geo_.points;
  const auto coordinates = section_view<format::Double2>(section);
  for (std::size_t i = 0; i < coordinates.size(); ++i)
    if (!std::isfinite(coordinates[i].x) || !std::isfinite(coordinates[i].y))
      fail_section(section, "point " + std::to_string(i) + " is not finite");
}

}  // namespace kiln
