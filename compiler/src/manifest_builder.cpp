#include "manifest_builder.hpp"

#include <zstd.h>

#include <cstring>
#include <map>

#include "accel_entry.hpp"
#include "kiln/schema/manifest_generated.h"

namespace kiln {

std::vector<std::byte> build_manifest(const Scene& scene, const BuildOptions& options,
                                      const GeometrySectionIndices& sections,
                                      std::span<const AccelEntry> accels,
                                      std::span<const std::vector<std::uint32_t>> accel_sections) {
  flatbuffers::FlatBufferBuilder fbb(1024);

  // Options that shape the output; thread counts do not, so they are not recorded.
  std::map<std::string, std::string> recorded;  // sorted by key
  recorded["compress"] =
      options.compression.enabled ? "zstd:" + std::to_string(options.compression.level) : "none";
  if (options.compression.enabled) recorded["zstd_version"] = ZSTD_versionString();
  std::vector<flatbuffers::Offset<schema::BuildOption>> option_offsets;
  for (const auto& [key, value] : recorded)
    option_offsets.push_back(schema::CreateBuildOptionDirect(fbb, key.c_str(), value.c_str()));

  std::vector<flatbuffers::Offset<schema::SourceFile>> sources;
  for (const auto& s : scene.sources)
    sources.push_back(schema::CreateSourceFileDirect(fbb, s.path.c_str(), s.size, s.xxh3));

  std::vector<flatbuffers::Offset<schema::Mesh>> meshes;
  for (const auto& m : scene.meshes)
    meshes.push_back(schema::CreateMeshDirect(fbb, m.name.c_str(), m.source_file, m.first_triangle,
                                              m.triangle_count, m.first_vertex, m.vertex_count));

  const EdgeTopology topology = edge_topology(scene);
  const schema::Bounds bounds(
      schema::Vec3(scene.bounds.min.x, scene.bounds.min.y, scene.bounds.min.z),
      schema::Vec3(scene.bounds.max.x, scene.bounds.max.y, scene.bounds.max.z));
  const auto stats = schema::CreateSceneStats(
      fbb, scene.positions.size(), scene.triangles.size(), &bounds, scene.input_triangle_count,
      scene.degenerate_triangles_dropped, !scene.normals.empty(), topology.boundary_edges,
      topology.non_manifold_edges, topology.closed() && !scene.triangles.empty());
  const auto geometry = schema::CreateGeometry(fbb, sections.positions, sections.triangles,
                                               sections.triangle_mesh, sections.normals);
  std::vector<flatbuffers::Offset<schema::Acceleration>> accelerations;
  for (std::size_t i = 0; i < accels.size(); ++i)
    accelerations.push_back(accels[i].describe(fbb, accel_sections[i]));
  const auto manifest =
      schema::CreateManifestDirect(fbb, kToolName, kToolVersion, &option_offsets, &sources, stats,
                                   &meshes, geometry, &accelerations);
  schema::FinishManifestBuffer(fbb, manifest);

  std::vector<std::byte> bytes(fbb.GetSize());
  std::memcpy(bytes.data(), fbb.GetBufferPointer(), bytes.size());
  return bytes;
}

}  // namespace kiln
