// The voxel DAG as the compiler registers it: "dag", its options, and its contribution to a
// blob: the DAG words, optionally the voxels' Morton codes and normals (the attachment),
// VoxelDagDesc with per-level statistics.

#include <cstdio>
#include <stdexcept>

#include "kiln/compiler/structure_builder.hpp"
#include "kiln/compiler/voxel_dag_builder.hpp"
#include "kiln/compiler/voxelizer.hpp"
#include "kiln/formats/voxel_dag.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/schema/manifest_generated.h"
#include "voxel_options.hpp"

namespace kiln {

extern const StructureBuilder kVoxelDagBuilder;

namespace {

std::vector<StructureOption> voxel_dag_options() {
  StructureOption cube{"cube-side",
                       "",
                       "0",
                       "--accel dag: sub-cube side of the out-of-core build (a power of two; 0: "
                       "from --memory-budget); never changes the output",
                       false,
                       parse_uint_in(0, format::kVoxelMaxResolution)};
  cube.enters_output = false;
  return {
      voxel_resolution_option(format::kVoxelMaxResolution),
      memory_budget_option(),
      cube,
      {"normals", "--voxel-normals", "false",
       "--accel dag: attach each voxel's averaged triangle normal", true, parse_switch()},
      {"solid", "--solid", "false",
       "--accel dag: fill the inside too (closed meshes: kiln dump says which)", true,
       parse_switch()},
  };
}

struct DagStorage {
  Voxels voxels;
  FlatVoxelDag dag;
};

std::string summary_of(const VoxelGrid& grid, const FlatVoxelDag& dag) {
  char line[256];
  std::snprintf(
      line, sizeof line, "%u^3: %llu voxels, %llu DAG bytes (%.3f bits/voxel), SVO/DAG %.2f",
      grid.resolution, (unsigned long long)dag.voxel_count, (unsigned long long)dag.dag_bytes,
      double(dag.dag_bytes) * 8.0 / double(dag.voxel_count),
      double(dag.svo_bytes) / double(dag.dag_bytes));
  return line;
}

// The description, given the blob's indices of the sections (words, then codes and normals when
// attached).
auto describe_with(const DagStorage& storage, bool normals, bool solid,
                   std::uint64_t surface_voxels) {
  const FlatVoxelDag& dag = storage.dag;
  return [=, grid = storage.voxels.grid, levels = dag.level_stats, leaf_first = dag.leaf_first_word,
          voxel_count = dag.voxel_count, svo_bytes = dag.svo_bytes, dag_bytes = dag.dag_bytes,
          level_count = dag.levels](flatbuffers::FlatBufferBuilder& fbb,
                                    std::span<const std::uint32_t> index) {
    std::vector<flatbuffers::Offset<schema::VoxelDagLevel>> level_tables;
    for (const auto& l : levels)
      level_tables.push_back(
          schema::CreateVoxelDagLevel(fbb, l.svo_nodes, l.dag_nodes, l.bytes, l.first_word));
    const double bits_per_voxel = double(dag_bytes) * 8.0 / double(voxel_count);
    const auto desc = schema::CreateVoxelDagDescDirect(
        fbb, grid.resolution, level_count, grid.origin[0], grid.origin[1], grid.origin[2],
        grid.voxel_size, index[0], normals ? index[1] : kNoSection, normals ? index[2] : kNoSection,
        leaf_first, voxel_count, &level_tables, svo_bytes, dag_bytes, bits_per_voxel, solid,
        surface_voxels);
    return std::pair{std::uint8_t(schema::StructureDesc::VoxelDagDesc), desc.o};
  };
}

// The surface DAG cube by cube (voxel_dag_builder.hpp): one code path at every resolution; with a
// budget that holds the whole grid it is one cube.
FlatVoxelDag surface_dag(const Scene& scene, const VoxelGrid& grid, const StructureRequest& request,
                         unsigned threads) {
  OutOfCoreDagOptions ooc;
  const std::string& budget = request.text_option("memory-budget");
  ooc.memory_budget = memory_budget_bytes(budget);
  ooc.cube_side = request.uint_option("cube-side");
  ooc.threads = threads;
  ooc.progress = terminal_progress();
  return build_voxel_dag_out_of_core(scene, grid, ooc);
}

BuiltStructure build(const Scene& scene, const StructureRequest& request, unsigned threads) {
  VoxelizeOptions options;
  options.resolution = request.uint_option("resolution");
  options.normals = request.switch_option("normals");
  options.solid = request.switch_option("solid");
  options.threads = threads;
  // Normals and the solid fill need every surface voxel at once.
  if ((options.normals || options.solid) && options.resolution > format::kVoxelInCoreMaxResolution)
    throw std::invalid_argument(
        "--accel dag: --solid and --voxel-normals work in core, up to "
        "--resolution " +
        std::to_string(format::kVoxelInCoreMaxResolution));
  auto storage = std::make_shared<DagStorage>();
  std::uint64_t surface_voxels = 0;
  if (options.normals || options.solid) {
    storage->voxels = voxelize_surface(scene, options);
    surface_voxels = storage->voxels.codes.size();
    storage->dag = options.solid ? build_voxel_dag(solid_leaves(scene, storage->voxels.grid,
                                                                storage->voxels.codes, threads),
                                                   options.resolution)
                                 : build_voxel_dag(storage->voxels.codes, options.resolution);
  } else {
    storage->voxels.grid = fit_voxel_grid(scene.bounds, options.resolution);
    storage->dag = surface_dag(scene, storage->voxels.grid, request, threads);
    surface_voxels = storage->dag.voxel_count;
  }
  if (!options.normals) std::vector<std::uint64_t>().swap(storage->voxels.codes);
  BuiltStructure built;
  built.sections = {raw_section(format::kSectionDagWords, storage->dag.words)};
  if (options.normals) {
    built.sections.push_back(raw_section(format::kSectionVoxelCodes, storage->voxels.codes));
    built.sections.push_back(raw_section(format::kSectionVoxelNormals, storage->voxels.normals));
  }
  built.describe = describe_with(*storage, options.normals, options.solid, surface_voxels);
  built.summary = summary_of(storage->voxels.grid, storage->dag);
  built.storage = std::move(storage);
  return built;
}

}  // namespace

const StructureBuilder kVoxelDagBuilder{"dag",
                                        "Sparse voxel DAG (Kampe et al. 2013)",
                                        InputKind::kTriangles,
                                        voxel_dag_options(),
                                        build,
                                        /*advise_variants=*/{},
                                        /*advise_skip=*/true};

}  // namespace kiln
