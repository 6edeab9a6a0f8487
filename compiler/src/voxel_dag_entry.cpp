// The voxel DAG's contribution to a blob: the DAG words, optionally the voxels' Morton codes and
// normals (the attachment), VoxelDagDesc with per-level statistics.
#include <cstdio>

#include "kiln/runtime/blob.hpp"

#include "accel_entry.hpp"
#include "kiln/compiler/voxel_dag_builder.hpp"
#include "kiln/compiler/voxelizer.hpp"
#include "kiln/formats/voxel_dag.hpp"

namespace kiln {

namespace {

struct DagStorage {
  Voxels voxels;
  FlatVoxelDag dag;
};

}  // namespace

AccelEntry make_voxel_dag_entry(const Scene& scene, const AccelRequest& request, unsigned threads) {
  VoxelizeOptions options = request.voxels;
  options.threads = threads;
  auto storage = std::make_shared<DagStorage>();
  storage->voxels = voxelize_surface(scene, options);
  storage->dag = options.solid ? build_voxel_dag(solid_leaves(scene, storage->voxels.grid,
                                                              storage->voxels.codes, threads),
                                                 options.resolution)
                               : build_voxel_dag(storage->voxels.codes, options.resolution);
  const std::uint64_t surface_voxels = storage->voxels.codes.size();
  if (!options.normals) std::vector<std::uint64_t>().swap(storage->voxels.codes);
  const FlatVoxelDag& dag = storage->dag;
  AccelEntry entry;
  entry.sections = {raw_section(format::kSectionDagWords, dag.words)};
  if (options.normals) {
    entry.sections.push_back(raw_section(format::kSectionVoxelCodes, storage->voxels.codes));
    entry.sections.push_back(raw_section(format::kSectionVoxelNormals, storage->voxels.normals));
  }
  const VoxelGrid grid = storage->voxels.grid;
  const auto levels = dag.level_stats;
  const std::uint64_t leaf_first = dag.leaf_first_word, voxel_count = dag.voxel_count,
                      svo_bytes = dag.svo_bytes, dag_bytes = dag.dag_bytes;
  const std::uint32_t level_count = dag.levels;
  const double bits_per_voxel = double(dag_bytes) * 8.0 / double(voxel_count);
  entry.describe = [=, kind = request.kind, normals = options.normals, solid = options.solid](
                       flatbuffers::FlatBufferBuilder& fbb, std::span<const std::uint32_t> index) {
    std::vector<flatbuffers::Offset<schema::VoxelDagLevel>> level_tables;
    for (const auto& l : levels)
      level_tables.push_back(
          schema::CreateVoxelDagLevel(fbb, l.svo_nodes, l.dag_nodes, l.bytes, l.first_word));
    const auto desc = schema::CreateVoxelDagDescDirect(
        fbb, grid.resolution, level_count, grid.origin[0], grid.origin[1], grid.origin[2],
        grid.voxel_size, index[0], normals ? index[1] : kNoSection, normals ? index[2] : kNoSection,
        leaf_first, voxel_count, &level_tables, svo_bytes, dag_bytes, bits_per_voxel, solid,
        surface_voxels);
    const std::vector<std::uint32_t> owned(index.begin(), index.end());
    return schema::CreateAccelerationDirect(fbb, kind.c_str(), &owned, 0, 0, 0, desc);
  };
  char line[256];
  std::snprintf(line, sizeof line,
                "%u^3: %llu voxels, %llu DAG bytes (%.3f bits/voxel), SVO/DAG %.2f",
                grid.resolution, (unsigned long long)voxel_count, (unsigned long long)dag_bytes,
                bits_per_voxel, double(svo_bytes) / double(dag_bytes));
  entry.summary = line;
  entry.storage = std::move(storage);
  return entry;
}

}  // namespace kiln
