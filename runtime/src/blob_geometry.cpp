// Semantic checks of the manifest's geometry references, and the typed views they guard.
#include <bit>
#include <string>

#include "kiln/formats/bvh.hpp"
#include "kiln/formats/esvo.hpp"
#include "kiln/formats/kdtree.hpp"
#include "kiln/formats/point_tree.hpp"
#include "kiln/formats/section_kinds.hpp"
#include "kiln/formats/voxel_dag.hpp"
#include "kiln/runtime/blob.hpp"

namespace kiln {

namespace {

std::string kind_name(std::uint32_t kind) {
  return format::fourcc_to_string(kind);
}

}  // namespace

void Blob::validate_geometry() {
  const schema::Manifest& m = *manifest_;
  const auto* scene = m.scene();
  const auto* geometry = m.geometry();
  if (scene == nullptr || geometry == nullptr) fail_section(0, "manifest lacks scene or geometry");
  const std::uint64_t vertex_count = scene->vertex_count();
  const std::uint64_t triangle_count = scene->triangle_count();

  // A geometry array: the right kind, element size and count, or absent when optional.
  auto check = [&](const char* what, std::uint32_t index, std::uint32_t kind,
                   std::uint32_t element_size, std::uint64_t count, bool optional) {
    if (index == kNoSection) {
      if (optional) return;
      fail_section(0, std::string("manifest names no ") + what + " section");
    }
    if (index >= sections_.size() || index == 0)
      fail_section(0, std::string("manifest's ") + what + " section index " +
                          std::to_string(index) + " is out of range");
    const auto& s = sections_[index];
    if (s.kind != kind)
      fail_section(index, std::string("manifest names it as ") + what + " but its kind is not " +
                              kind_name(kind));
    if (s.element_size != element_size)
      fail_section(index, "element size " + std::to_string(s.element_size) + ", expected " +
                              std::to_string(element_size));
    if (s.element_count != count)
      fail_section(index, std::to_string(s.element_count) + " elements, the manifest says " +
                              std::to_string(count));
  };
  check("positions", geometry->positions(), format::kSectionPositions, sizeof(format::Float3),
        vertex_count, false);
  check("triangles", geometry->triangles(), format::kSectionTriangles, sizeof(format::Triangle),
        triangle_count, false);
  check("triangle-mesh", geometry->triangle_mesh(), format::kSectionTriangleMesh,
        sizeof(std::uint32_t), triangle_count, false);
  check("normals", geometry->normals(), format::kSectionNormals, sizeof(format::Float3),
        vertex_count, true);
  if (scene->has_normals() != (geometry->normals() != kNoSection))
    fail_section(0, "scene.has_normals disagrees with the geometry's normals section");

  const std::uint32_t source_count = m.sources() ? m.sources()->size() : 0;
  if (m.meshes() != nullptr) {
    for (std::uint32_t i = 0; i < m.meshes()->size(); ++i) {
      const auto* mesh = m.meshes()->Get(i);
      const auto where = "mesh " + std::to_string(i);
      if (mesh->source_file() >= source_count)
        fail_section(0, where + " names source file " + std::to_string(mesh->source_file()) +
                            " of " + std::to_string(source_count));
      if (mesh->first_triangle() > triangle_count ||
          mesh->triangle_count() > triangle_count - mesh->first_triangle())
        fail_section(0, where + " triangle range is out of bounds");
      if (mesh->first_vertex() > vertex_count ||
          mesh->vertex_count() > vertex_count - mesh->first_vertex())
        fail_section(0, where + " vertex range is out of bounds");
    }
  }
  if (m.accelerations() != nullptr) {
    for (const auto* accel : *m.accelerations()) {
      const std::string kind = accel->kind()->str();
      if (accel->sections() != nullptr)
        for (const std::uint32_t index : *accel->sections())
          if (index == 0 || index >= sections_.size())
            fail_section(0, "acceleration '" + kind + "' names section " + std::to_string(index) +
                                ", out of range");
      if (const auto* bvh = accel->bvh()) {
        const auto where = "acceleration '" + kind + "' ";
        check((where + "nodes").c_str(), bvh->nodes(), format::kSectionBvhNodes,
              sizeof(format::BvhNode), bvh->node_count(), false);
        check((where + "triangles").c_str(), bvh->triangles(), format::kSectionBvhTriangles,
              sizeof(format::RayTriangle), bvh->reference_count(), false);
        check((where + "primitive ids").c_str(), bvh->prim_ids(), format::kSectionBvhPrimIds,
              sizeof(std::uint32_t), bvh->reference_count(), false);
        if (bvh->node_count() == 0) fail_section(0, where + "has no nodes");
      }
      if (const auto* kd = accel->kdtree()) {
        const auto where = "acceleration '" + kind + "' ";
        check((where + "nodes").c_str(), kd->nodes(), format::kSectionKdNodes,
              sizeof(format::KdNode), kd->node_count(), false);
        check((where + "primitive ids").c_str(), kd->prim_ids(), format::kSectionKdPrimIds,
              sizeof(std::uint32_t), kd->reference_count(), false);
        check((where + "triangles").c_str(), kd->triangles(), format::kSectionKdTriangles,
              sizeof(format::RayTriangle), triangle_count, false);
        if (kd->node_count() == 0) fail_section(0, where + "has no nodes");
        if (kd->bounds() == nullptr) fail_section(0, where + "has no bounds");
      }
      if (const auto* pt = accel->points()) {
        // Over every scene vertex: the ids are vertex indices.
        const auto where = "acceleration '" + kind + "' ";
        if (pt->point_count() != vertex_count)
          fail_section(0, where + "holds " + std::to_string(pt->point_count()) +
                              " points, the scene " + std::to_string(vertex_count) + " vertices");
        check((where + "nodes").c_str(), pt->nodes(), format::kSectionPointNodes,
              sizeof(format::PointNode), pt->node_count(), false);
        check((where + "points").c_str(), pt->points(), format::kSectionPointPositions,
              sizeof(format::Float3), vertex_count, false);
        check((where + "point ids").c_str(), pt->point_ids(), format::kSectionPointIds,
              sizeof(std::uint32_t), vertex_count, false);
        if (pt->node_count() == 0) fail_section(0, where + "has no nodes");
        if (pt->bounds() == nullptr) fail_section(0, where + "has no bounds");
      }
      if (const auto* dag = accel->dag()) {
        const auto where = "acceleration '" + kind + "' ";
        check((where + "words").c_str(), dag->words(), format::kSectionDagWords,
              sizeof(std::uint32_t), dag->dag_bytes() / 4, false);
        const bool has_codes = dag->voxel_codes() != kNoSection;
        if (has_codes != (dag->voxel_normals() != kNoSection))
          fail_section(0, where + "has voxel codes without normals or the reverse");
        check((where + "voxel codes").c_str(), dag->voxel_codes(), format::kSectionVoxelCodes,
              sizeof(std::uint64_t), dag->surface_voxel_count(), true);
        check((where + "voxel normals").c_str(), dag->voxel_normals(), format::kSectionVoxelNormals,
              sizeof(std::uint32_t), dag->surface_voxel_count(), true);
        if (dag->level_stats() == nullptr) fail_section(0, where + "has no level table");
      }
      if (const auto* e = accel->esvo()) {
        const auto where = "acceleration '" + kind + "' ";
        const std::uint64_t pages =
            (e->word_count() + format::kEsvoPageWords - 1) / format::kEsvoPageWords;
        check((where + "words").c_str(), e->words(), format::kSectionEsvoWords,
              sizeof(std::uint32_t), e->word_count(), false);
        check((where + "page headers").c_str(), e->pages(), format::kSectionEsvoPages,
              sizeof(std::uint32_t), pages, false);
        check((where + "blocks").c_str(), e->blocks(), format::kSectionEsvoBlocks,
              sizeof(format::EsvoBlockInfo), e->block_count(), false);
        check((where + "normals").c_str(), e->normals(), format::kSectionEsvoNormals,
              sizeof(std::uint32_t), e->voxel_count(), false);
        check((where + "colours").c_str(), e->colors(), format::kSectionEsvoColors,
              sizeof(std::uint32_t), e->voxel_count(), true);
        // levels is log2(resolution): kiln dump sizes its table by it, so the two must agree.
        if (e->levels() != std::uint32_t(std::bit_width(e->resolution())) - 1)
          fail_section(0, where + "has " + std::to_string(e->levels()) + " levels at resolution " +
                              std::to_string(e->resolution()));
        if (e->level_stats() == nullptr || e->level_stats()->size() != e->levels())
          fail_section(0,
                       where + "has no level table of " + std::to_string(e->levels()) + " levels");
      }
    }
  }
}

std::span<const format::Float3> Blob::positions() const {
  return section_view<format::Float3>(manifest_->geometry()->positions());
}

std::span<const format::Float3> Blob::normals() const {
  return section_view<format::Float3>(manifest_->geometry()->normals());
}

std::span<const format::Triangle> Blob::triangles() const {
  return section_view<format::Triangle>(manifest_->geometry()->triangles());
}

std::span<const std::uint32_t> Blob::triangle_mesh_ids() const {
  return section_view<std::uint32_t>(manifest_->geometry()->triangle_mesh());
}

}  // namespace kiln
