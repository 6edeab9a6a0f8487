// The blob's input: O(1) checks of the manifest's input table and its section references, and
// the plain accessors over it.
#include <string>

#include "kiln/formats/section_kinds.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/manifest.hpp"

namespace kiln {

InputInfo validate_event_input(const Blob& blob, const schema::EventTable& table);

namespace {

format::Box3f to_box(const schema::Bounds* b) {
  if (b == nullptr) return {{0, 0, 0}, {0, 0, 0}};
  return {{b->min().x(), b->min().y(), b->min().z()}, {b->max().x(), b->max().y(), b->max().z()}};
}

std::string text(const flatbuffers::String* s) {
  return s ? s->str() : std::string();
}

// Each mesh names a recorded source file and ranges inside the scene's arrays.
void check_meshes(const Blob& blob, const schema::TriangleScene& scene,
                  std::uint32_t source_count) {
  if (scene.meshes() == nullptr) return;
  const std::uint64_t vertex_count = scene.vertex_count(), triangle_count = scene.triangle_count();
  for (std::uint32_t i = 0; i < scene.meshes()->size(); ++i) {
    const auto* mesh = scene.meshes()->Get(i);
    const auto where = "mesh " + std::to_string(i);
    if (mesh->source_file() >= source_count)
      blob.fail_section(0, where + " names source file " + std::to_string(mesh->source_file()) +
                               " of " + std::to_string(source_count));
    if (mesh->first_triangle() > triangle_count ||
        mesh->triangle_count() > triangle_count - mesh->first_triangle())
      blob.fail_section(0, where + " triangle range is out of bounds");
    if (mesh->first_vertex() > vertex_count ||
        mesh->vertex_count() > vertex_count - mesh->first_vertex())
      blob.fail_section(0, where + " vertex range is out of bounds");
  }
}

}  // namespace

void Blob::check_section(const std::string& what, std::uint32_t index, std::uint32_t kind,
                         std::uint32_t element_size, std::uint64_t count, bool optional) const {
  if (index == kNoSection) {
    if (optional) return;
    fail_section(0, "manifest names no " + what + " section");
  }
  if (index >= sections_.size() || index == 0)
    fail_section(
        0, "manifest's " + what + " section index " + std::to_string(index) + " is out of range");
  const auto& s = sections_[index];
  if (s.kind != kind)
    fail_section(index, "manifest names it as " + what + " but its kind is not " +
                            format::fourcc_to_string(kind));
  if (s.element_size != element_size)
    fail_section(index, "element size " + std::to_string(s.element_size) + ", expected " +
                            std::to_string(element_size));
  if (s.element_count != count)
    fail_section(index, std::to_string(s.element_count) + " elements, the manifest says " +
                            std::to_string(count));
}

void Blob::validate_input() {
  const schema::Manifest& m = manifest_of(*this);
  if (const auto* scene = m.input_as_TriangleScene()) {
    const std::uint64_t vertex_count = scene->vertex_count();
    const std::uint64_t triangle_count = scene->triangle_count();
    check_section("positions", scene->positions(), format::kSectionPositions,
                  sizeof(format::Float3), vertex_count, false);
    check_section("triangles", scene->triangles(), format::kSectionTriangles,
                  sizeof(format::Triangle), triangle_count, false);
    check_section("triangle-mesh", scene->triangle_mesh(), format::kSectionTriangleMesh,
                  sizeof(std::uint32_t), triangle_count, false);
    check_section("normals", scene->normals(), format::kSectionNormals, sizeof(format::Float3),
                  vertex_count, true);
    check_meshes(*this, *scene, m.sources() ? m.sources()->size() : 0);
    positions_ = scene->positions(), triangles_ = scene->triangles();
    triangle_mesh_ = scene->triangle_mesh(), normals_ = scene->normals();
    input_ = {InputKind::kTriangles,
              vertex_count,
              triangle_count,
              to_box(scene->bounds()),
              scene->input_triangle_count(),
              scene->degenerate_triangles_dropped(),
              normals_ != kNoSection,
              scene->boundary_edges(),
              scene->non_manifold_edges(),
              scene->closed(),
              0,
              {}};
  } else if (const auto* set = m.input_as_PointCloud()) {
    check_section("positions", set->positions(), format::kSectionPositions, sizeof(format::Float3),
                  set->point_count(), false);
    positions_ = set->positions();
    input_ = {};
    input_.kind = InputKind::kPoint3;
    input_.vertex_count = set->point_count();
    input_.bounds = to_box(set->bounds());
  } else if (const auto* events = m.input_as_EventTable()) {
    input_ = validate_event_input(*this, *events);  // issue 18: blob_events.cpp
  } else if (m.input_type() == schema::Input::PolygonLayer) {
    validate_polygon_layer();
  } else if (m.input_type() == schema::Input::PointTable) {
    validate_point_table();
  } else if (m.input_type() == schema::Input::NONE) {
    fail_section(0, "manifest names no input");
  } else {
    fail_section(0, "unknown input kind " + std::to_string(unsigned(m.input_type())) +
                        " (written by a newer kiln?)");
  }
}

std::string Blob::tool_name() const {
  return text(manifest_of(*this).tool_name());
}

std::string Blob::tool_version() const {
  return text(manifest_of(*this).tool_version());
}

std::vector<std::pair<std::string, std::string>> Blob::options() const {
  std::vector<std::pair<std::string, std::string>> out;
  if (const auto* options = manifest_of(*this).options())
    for (const auto* option : *options)
      out.emplace_back(option->key()->str(), option->value()->str());
  return out;
}

std::vector<SourceInfo> Blob::sources() const {
  std::vector<SourceInfo> out;
  if (const auto* sources = manifest_of(*this).sources())
    for (const auto* source : *sources)
      out.push_back({source->path()->str(), source->size(), source->xxh3()});
  return out;
}

std::size_t Blob::mesh_count() const {
  const auto* scene = manifest_of(*this).input_as_TriangleScene();
  return scene != nullptr && scene->meshes() != nullptr ? scene->meshes()->size() : 0;
}

MeshInfo Blob::mesh(std::size_t index) const {
  if (index >= mesh_count()) fail("mesh " + std::to_string(index) + " is out of range");
  const auto* mesh =
      manifest_of(*this).input_as_TriangleScene()->meshes()->Get(std::uint32_t(index));
  return {text(mesh->name()),     mesh->source_file(),  mesh->first_triangle(),
          mesh->triangle_count(), mesh->first_vertex(), mesh->vertex_count()};
}

std::span<const format::Float3> Blob::positions() const {
  return section_view<format::Float3>(positions_);
}

std::span<const format::Float3> Blob::normals() const {
  return section_view<format::Float3>(normals_);
}

std::span<const format::Triangle> Blob::triangles() const {
  return section_view<format::Triangle>(triangles_);
}

std::span<const std::uint32_t> Blob::triangle_mesh_ids() const {
  return section_view<std::uint32_t>(triangle_mesh_);
}

}  // namespace kiln
