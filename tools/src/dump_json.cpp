// `kiln dump --json`: header, sections and manifest; each structure's part is its kind's
// description (fields, then tables as arrays of objects) under the kind's name.
#include <nlohmann/json.hpp>
#include <string>
#include <variant>

#include "dump_writers.hpp"
#include "kiln/formats/section_kinds.hpp"

namespace kiln::dump {

namespace {

using Json = nlohmann::ordered_json;

Json header_json(const format::FileHeader& h) {
  return {{"version", std::to_string(h.version_major) + "." + std::to_string(h.version_minor)},
          {"header_size", h.header_size},
          {"flags", h.flags},
          {"file_size", h.file_size},
          {"section_table_offset", h.section_table_offset},
          {"section_count", h.section_count},
          {"section_entry_size", h.section_entry_size},
          {"section_table_checksum", hex64(h.section_table_checksum)},
          {"header_checksum", hex64(h.header_checksum)}};
}

Json sections_json(const Blob& blob) {
  Json sections = Json::array();
  for (const auto& s : blob.sections())
    sections.push_back({{"kind", format::fourcc_to_string(s.kind)},
                        {"required", is_required(s)},
                        {"codec", codec_name(s.codec)},
                        {"alignment", std::uint64_t{1} << s.alignment_log2},
                        {"offset", s.offset},
                        {"stored_size", s.stored_size},
                        {"raw_size", s.raw_size},
                        {"element_count", s.element_count},
                        {"element_size", s.element_size},
                        {"xxh3", hex64(s.checksum)}});
  return sections;
}

Json bounds_json(const format::Box3f& b) {
  return {{"min", {b.min.x, b.min.y, b.min.z}}, {"max", {b.max.x, b.max.y, b.max.z}}};
}

Json bounds2_json(const format::Box2d& b) {
  return {{"min", {b.min.x, b.min.y}}, {"max", {b.max.x, b.max.y}}};
}

// A polygon layer's or a point table's counts and exact bounds.
Json geo_input_json(const Blob& blob) {
  const InputInfo& in = blob.input();
  if (in.kind == InputKind::kPolygons2) {
    const PolygonLayerView layer = blob.polygon_layer();
    return {{"feature_count", layer.feature_count()},     {"polygon_count", layer.polygon_count()},
            {"ring_count", layer.ring_count()},           {"vertex_count", layer.vertices.size()},
            {"features_skipped", layer.features_skipped}, {"name_property", layer.name_property},
            {"bounds", bounds2_json(in.bounds2)}};
  }
  const PointTableView table = blob.point_table();
  return {{"point_count", table.points.size()}, {"row_count", table.feature_count()},
          {"rows_skipped", table.rows_skipped}, {"x_column", table.x_column},
          {"y_column", table.y_column},         {"bounds", bounds2_json(in.bounds2)}};
}

// A triangle scene's counts and topology, or a 3D point set's size.
Json input_json(const Blob& blob) {
  const InputInfo& in = blob.input();
  if (in.kind == InputKind::kPolygons2 || in.kind == InputKind::kPoint2)
    return geo_input_json(blob);
  if (in.kind != InputKind::kTriangles)
    return {{"point_count", in.vertex_count}, {"bounds", bounds_json(in.bounds)}};
  return {{"vertex_count", in.vertex_count},
          {"triangle_count", in.triangle_count},
          {"input_triangle_count", in.input_triangle_count},
          {"degenerate_triangles_dropped", in.degenerate_triangles_dropped},
          {"has_normals", in.has_normals},
          {"closed", in.closed},
          {"boundary_edges", in.boundary_edges},
          {"non_manifold_edges", in.non_manifold_edges},
          {"mesh_count", blob.mesh_count()},
          {"bounds", bounds_json(in.bounds)}};
}

Json meshes_json(const Blob& blob) {
  Json meshes = Json::array();
  for (std::size_t i = 0; i < blob.mesh_count(); ++i) {
    const MeshInfo m = blob.mesh(i);
    meshes.push_back({{"name", m.name},
                      {"source_file", m.source_file},
                      {"first_triangle", m.first_triangle},
                      {"triangle_count", m.triangle_count},
                      {"first_vertex", m.first_vertex},
                      {"vertex_count", m.vertex_count}});
  }
  return meshes;
}

Json value_json(const DescValue& value) {
  return std::visit([](const auto& v) { return Json(v); }, value);
}

// The description's fields, then each table as an array of objects under its key.
Json description_json(const Description& d) {
  Json json = Json::object();
  for (const auto& [key, value] : d.fields) json[key] = value_json(value);
  for (const DescTable& table : d.tables) {
    Json rows = Json::array();
    for (const auto& row : table.rows) {
      Json object = Json::object();
      for (std::size_t c = 0; c < row.size() && c < table.columns.size(); ++c)
        object[table.columns[c]] = value_json(row[c]);
      rows.push_back(std::move(object));
    }
    json[table.key] = std::move(rows);
  }
  return json;
}

Json structures_json(const Blob& blob) {
  Json structures = Json::array();
  for (const StructureInfo& info : blob.structures())
    structures.push_back({{"name", info.name},
                          {"kind", info.kind},
                          {"sections", info.sections},
                          {info.kind, description_json(describe(blob, info))}});
  return structures;
}

Json manifest_json(const Blob& blob) {
  Json options = Json::object();
  for (const auto& [key, value] : blob.options()) options[key] = value;
  Json sources = Json::array();
  for (const SourceInfo& s : blob.sources())
    sources.push_back({{"path", s.path}, {"size", s.size}, {"xxh3", hex64(s.xxh3)}});
  const bool triangles = blob.input().kind == InputKind::kTriangles;
  Json manifest = {{"tool_name", blob.tool_name()},
                   {"tool_version", blob.tool_version()},
                   {"options", std::move(options)},
                   {"sources", std::move(sources)},
                   {"input", input_kind_name(blob.input().kind)}};
  const InputKind kind = blob.input().kind;
  manifest[triangles                       ? "scene"
           : kind == InputKind::kPolygons2 ? "polygon_layer"
           : kind == InputKind::kPoint2    ? "point_table"
                                           : "point_set"] = input_json(blob);
  manifest["meshes"] = meshes_json(blob);
  manifest["structures"] = structures_json(blob);
  const std::vector<Description> advice = describe_advice(blob);
  if (!advice.empty()) {
    manifest["advice"] = Json::array();
    for (const Description& d : advice) manifest["advice"].push_back(description_json(d));
  }
  return manifest;
}

}  // namespace

void write_json(const Blob& blob, std::ostream& out) {
  const Json json = {{"file", blob.name()},
                     {"header", header_json(blob.header())},
                     {"sections", sections_json(blob)},
                     {"manifest", manifest_json(blob)}};
  out << json.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) << '\n';
}

}  // namespace kiln::dump
