#include "geo_input.hpp"

#include "kiln/formats/section_kinds.hpp"
#include "kiln/schema/manifest_generated.h"

namespace kiln {

namespace {

template <class T>
std::span<const std::byte> bytes_of(const std::vector<T>& values) {
  return std::as_bytes(std::span<const T>(values));
}

std::span<const std::byte> bytes_of(const std::string& text) {
  return std::as_bytes(std::span<const char>(text.data(), text.size()));
}

void add_strings(const StringColumn& column, std::uint32_t& offsets, std::uint32_t& bytes,
                 const AddSection& add) {
  offsets = add(format::kSectionStringOffsets, sizeof(std::uint64_t), column.offsets.size(),
                bytes_of(column.offsets));
  bytes = add(format::kSectionStringBytes, 1, column.bytes.size(), bytes_of(column.bytes));
}

schema::Bounds2d bounds_of(const format::Box2d& box) {
  if (box.empty()) return schema::Bounds2d(schema::Vec2d(0, 0), schema::Vec2d(0, 0));
  return schema::Bounds2d(schema::Vec2d(box.min.x, box.min.y), schema::Vec2d(box.max.x, box.max.y));
}

}  // namespace

void add_geo_input_sections(const Scene& scene, InputSectionIndices& in, const AddSection& add) {
  constexpr std::uint32_t kOffset = sizeof(std::uint64_t);
  if (const PolygonLayer* layer = scene.polygons ? &*scene.polygons : nullptr) {
    in.vertices = add(format::kSectionLayerVertices, sizeof(format::Double2),
                      layer->vertices.size(), bytes_of(layer->vertices));
    in.ring_vertices = add(format::kSectionLayerRings, kOffset, layer->ring_vertices.size(),
                           bytes_of(layer->ring_vertices));
    in.polygon_rings = add(format::kSectionLayerPolygons, kOffset, layer->polygon_rings.size(),
                           bytes_of(layer->polygon_rings));
    in.feature_polygons = add(format::kSectionLayerFeatures, kOffset,
                              layer->feature_polygons.size(), bytes_of(layer->feature_polygons));
    add_strings(layer->ids, in.id_offsets, in.id_bytes, add);
    add_strings(layer->names, in.name_offsets, in.name_bytes, add);
  } else if (const PointTable2* table = scene.points2 ? &*scene.points2 : nullptr) {
    in.points = add(format::kSectionPoints2, sizeof(format::Double2), table->points.size(),
                    bytes_of(table->points));
    if (!table->feature_points.empty())
      in.feature_points = add(format::kSectionPointFeatures, kOffset, table->feature_points.size(),
                              bytes_of(table->feature_points));
    if (table->ids.size() > 0 || table->names.size() > 0) {
      add_strings(table->ids, in.id_offsets, in.id_bytes, add);
      add_strings(table->names, in.name_offsets, in.name_bytes, add);
    }
  }
}

std::pair<std::uint8_t, std::uint32_t> geo_input_table(flatbuffers::FlatBufferBuilder& fbb,
                                                       const Scene& scene,
                                                       const InputSectionIndices& in) {
  if (scene.polygons) {
    const PolygonLayer& layer = *scene.polygons;
    const schema::Bounds2d bounds = bounds_of(layer.bounds);
    const auto table = schema::CreatePolygonLayerDirect(
        fbb, layer.feature_count(), layer.polygon_count(), layer.ring_count(),
        layer.vertices.size(), &bounds, layer.features_skipped, layer.name_property.c_str(),
        in.vertices, in.ring_vertices, in.polygon_rings, in.feature_polygons, in.id_offsets,
        in.id_bytes, in.name_offsets, in.name_bytes);
    return {std::uint8_t(schema::Input::PolygonLayer), table.o};
  }
  const PointTable2& points = *scene.points2;
  const schema::Bounds2d bounds = bounds_of(points.bounds);
  const auto table = schema::CreatePointTableDirect(
      fbb, points.points.size(), points.feature_count(), &bounds, points.rows_skipped,
      points.x_column.c_str(), points.y_column.c_str(), points.name_property.c_str(), in.points,
      in.feature_points, in.id_offsets, in.id_bytes, in.name_offsets, in.name_bytes);
  return {std::uint8_t(schema::Input::PointTable), table.o};
}

}  // namespace kiln
