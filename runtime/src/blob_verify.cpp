// The deep check behind `kiln verify`: everything open() skipped because it is O(bytes): the
// container's checksums and padding, the input's indices, then each structure's kind's verify.
#include <cmath>
#include <string>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/checksum.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/structure_registry.hpp"

namespace kiln {

void Blob::verify() const {
  std::uint64_t previous_end =
      header_.section_table_offset + sections_.size() * sizeof(format::SectionEntry);
  for (std::uint32_t i = 0; i < sections_.size(); ++i) {
    const auto& s = sections_[i];
    for (std::uint64_t p = previous_end; p < s.offset; ++p)
      if (bytes_[p] != std::byte{0})
        fail("padding byte at offset " + std::to_string(p) + " before section " +
             std::to_string(i) + " is not zero");
    previous_end = s.offset + s.stored_size;
    if (xxh3_64(bytes_.subspan(s.offset, s.stored_size)) != s.checksum)
      fail_section(i, "checksum mismatch (payload is corrupt)");
  }
  verify_input();
  for (const StructureInfo& info : structures_) find_structure_kind(info.kind)->verify(*this, info);
}

// Finite positions, triangles naming stored vertices, and each mesh owning its triangle range
// with its triangles indexing only its own vertices.
void Blob::verify_input() const {
  if (input_.kind == InputKind::kPolygons2 || input_.kind == InputKind::kPoint2)
    return verify_geo_input();
  const auto scene_positions = positions();
  for (std::size_t v = 0; v < scene_positions.size(); ++v) {
    const auto& p = scene_positions[v];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      fail_section(positions_, "vertex " + std::to_string(v) + " is not finite");
  }
  const auto vertex_count = scene_positions.size();
  const auto scene_triangles = triangles();
  for (std::size_t t = 0; t < scene_triangles.size(); ++t)
    for (const std::uint32_t v : scene_triangles[t].v)
      if (v >= vertex_count)
        fail_section(triangles_, "triangle " + std::to_string(t) + " names vertex " +
                                     std::to_string(v) + " of " + std::to_string(vertex_count));
  const auto mesh_ids = triangle_mesh_ids();
  if (mesh_ids.empty()) return;
  const auto* meshes = manifest_of(*this).input_as_TriangleScene()->meshes();
  const std::uint32_t mesh_count = meshes ? meshes->size() : 0;
  for (std::size_t t = 0; t < mesh_ids.size(); ++t) {
    const std::uint32_t id = mesh_ids[t];
    const auto where = "triangle " + std::to_string(t);
    if (id >= mesh_count)
      fail_section(triangle_mesh_, where + " names mesh " + std::to_string(id) + " of " +
                                       std::to_string(mesh_count));
    const auto* mesh = meshes->Get(id);
    if (t < mesh->first_triangle() || t - mesh->first_triangle() >= mesh->triangle_count())
      fail_section(triangle_mesh_,
                   where + " lies outside the range of its mesh " + std::to_string(id));
    for (const std::uint32_t v : scene_triangles[t].v)
      if (v < mesh->first_vertex() || v - mesh->first_vertex() >= mesh->vertex_count())
        fail_section(triangles_,
                     where + " names vertex " + std::to_string(v) + " outside its mesh");
  }
}

}  // namespace kiln
