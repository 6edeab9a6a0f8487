#include "manifest_builder.hpp"

#include <zstd.h>

#include <algorithm>
#include <cstring>
#include <map>

#include "event_table_sections.hpp"
#include "geo_input.hpp"
#include "kiln/schema/manifest_generated.h"

namespace kiln {

namespace {

using flatbuffers::FlatBufferBuilder;
using flatbuffers::Offset;

// Options that shape the output; thread counts do not, so they are not recorded.
std::vector<Offset<schema::BuildOption>> recorded_options(FlatBufferBuilder& fbb,
                                                          const BuildOptions& options) {
  std::map<std::string, std::string> recorded;  // sorted by key
  recorded["compress"] =
      options.compression.enabled ? "zstd:" + std::to_string(options.compression.level) : "none";
  if (options.compression.enabled) recorded["zstd_version"] = ZSTD_versionString();
  std::vector<Offset<schema::BuildOption>> offsets;
  for (const auto& [key, value] : recorded)
    offsets.push_back(schema::CreateBuildOptionDirect(fbb, key.c_str(), value.c_str()));
  return offsets;
}

schema::Bounds bounds_of(const Scene& scene) {
  return schema::Bounds(schema::Vec3(scene.bounds.min.x, scene.bounds.min.y, scene.bounds.min.z),
                        schema::Vec3(scene.bounds.max.x, scene.bounds.max.y, scene.bounds.max.z));
}

Offset<void> triangle_scene(FlatBufferBuilder& fbb, const Scene& scene,
                            const InputSectionIndices& input) {
  std::vector<Offset<schema::Mesh>> meshes;
  for (const auto& m : scene.meshes)
    meshes.push_back(schema::CreateMeshDirect(fbb, m.name.c_str(), m.source_file, m.first_triangle,
                                              m.triangle_count, m.first_vertex, m.vertex_count));
  const EdgeTopology topology = edge_topology(scene);
  const schema::Bounds bounds = bounds_of(scene);
  return schema::CreateTriangleSceneDirect(
             fbb, scene.positions.size(), scene.triangles.size(), &bounds,
             scene.input_triangle_count, scene.degenerate_triangles_dropped,
             topology.boundary_edges, topology.non_manifold_edges, topology.closed(), &meshes,
             input.positions, input.triangles, input.triangle_mesh, input.normals)
      .Union();
}

Offset<void> point_set(FlatBufferBuilder& fbb, const Scene& scene,
                       const InputSectionIndices& input) {
  const schema::Bounds bounds = bounds_of(scene);
  return schema::CreatePointCloud(fbb, scene.positions.size(), &bounds, input.positions).Union();
}

std::vector<Offset<schema::Structure>> structures(
    FlatBufferBuilder& fbb, const BuildOptions& options, std::span<const BuiltStructure> built,
    std::span<const std::vector<std::uint32_t>> sections) {
  std::vector<Offset<schema::Structure>> offsets;
  for (std::size_t i = 0; i < built.size(); ++i) {
    const auto [type, desc] = built[i].describe(fbb, sections[i]);
    offsets.push_back(schema::CreateStructureDirect(
        fbb, options.structures[i].name.c_str(), options.structures[i].kind.c_str(), &sections[i],
        schema::StructureDesc(type), Offset<void>(desc)));
  }
  return offsets;
}

// Each `--accel auto`'s choice and table: deterministic columns only (no timing).
std::vector<Offset<schema::Advice>> advice_tables(FlatBufferBuilder& fbb,
                                                  const BuildOptions& options,
                                                  std::span<const AutoChoice> choices) {
  std::vector<Offset<schema::Advice>> offsets;
  for (const AutoChoice& choice : choices) {
    const Advice& a = choice.advice;
    std::vector<Offset<schema::AdviceRow>> rows;
    for (const AdviceRow& row : a.rows) {
      double nodes = 0, tests = 0;
      for (const AdviseRayMeasure& m : row.rays) nodes += m.nodes_per_ray, tests += m.tests_per_ray;
      const double kinds = double(std::max<std::size_t>(row.rays.size(), 1));
      rows.push_back(schema::CreateAdviceRowDirect(fbb, row.spec.c_str(), row.kind.c_str(),
                                                   row.bytes, row.bytes_per_triangle, nodes / kinds,
                                                   tests / kinds));
    }
    const std::string rays = a.ray_kinds.size() == 1 ? a.ray_kinds.front() : "both";
    offsets.push_back(schema::CreateAdviceDirect(
        fbb, options.structures[choice.structure].name.c_str(), choice.spec.c_str(),
        std::string(priority_name(a.priority)).c_str(), rays.c_str(),
        a.recommendation.reason.c_str(), a.scene_triangles, a.sample_triangles, a.rays_per_kind,
        a.seed, &rows));
  }
  return offsets;
}

}  // namespace

std::vector<std::byte> build_manifest(const Scene& scene, const BuildOptions& options,
                                      const InputSectionIndices& input,
                                      std::span<const BuiltStructure> built,
                                      std::span<const std::vector<std::uint32_t>> sections,
                                      std::span<const AutoChoice> advice) {
  FlatBufferBuilder fbb(1024);
  const auto option_offsets = recorded_options(fbb, options);
  std::vector<Offset<schema::SourceFile>> sources;
  for (const auto& s : scene.sources)
    sources.push_back(schema::CreateSourceFileDirect(fbb, s.path.c_str(), s.size, s.xxh3));
  const InputKind kind = input_kind_of(scene);
  schema::Input input_type = schema::Input::TriangleScene;
  Offset<void> input_table;
  if (kind == InputKind::kTriangles) {
    input_table = triangle_scene(fbb, scene, input);
  } else if (kind == InputKind::kEvents) {  // issue 18 (event_table_sections.cpp)
    input_type = schema::Input::EventTable;
    input_table = Offset<void>(event_table_manifest(fbb, *scene.events, input));
  } else if (kind == InputKind::kPoint3) {
    input_type = schema::Input::PointCloud, input_table = point_set(fbb, scene, input);
  } else {
    const auto [type, offset] = geo_input_table(fbb, scene, input);
    input_type = schema::Input(type), input_table = Offset<void>(offset);
  }
  const auto structure_offsets = structures(fbb, options, built, sections);
  const auto advice_offsets = advice_tables(fbb, options, advice);
  const auto manifest = schema::CreateManifestDirect(
      fbb, kToolName, kToolVersion, &option_offsets, &sources, input_type, input_table,
      &structure_offsets, advice.empty() ? nullptr : &advice_offsets);
  schema::FinishManifestBuffer(fbb, manifest);
  std::vector<std::byte> bytes(fbb.GetSize());
  std::memcpy(bytes.data(), fbb.GetBufferPointer(), bytes.size());
  return bytes;
}

}  // namespace kiln
