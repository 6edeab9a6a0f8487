// The symmetry-aware sparse voxel DAG as the compiler registers it: "ssvdag", its options, and
// its contribution to a blob: the node words, the leaf masks and SsvdagDesc with per-level
// statistics beside the DAG's.
#include <cstdio>
#include <stdexcept>
#include <string>

#include "kiln/compiler/ssvdag_builder.hpp"
#include "kiln/compiler/structure_builder.hpp"
#include "kiln/compiler/voxel_dag_builder.hpp"
#include "kiln/compiler/voxelizer.hpp"
#include "kiln/formats/ssvdag.hpp"
#include "kiln/formats/voxel_grid.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/schema/manifest_generated.h"
#include "voxel_options.hpp"

namespace kiln {

extern const StructureBuilder kSsvdagBuilder;

namespace {

std::vector<StructureOption> ssvdag_options() {
  return {
      voxel_resolution_option(format::kVoxelMaxResolution),
      memory_budget_option(),
      {"solid", "--solid", "false",
       "--accel ssvdag: fill the inside too (closed meshes), as --accel dag does", true,
       parse_switch()},
  };
}

struct SsvdagStorage {
  VoxelGrid grid;
  FlatSsvdag ssvdag;
};

std::string summary_of(const VoxelGrid& grid, const FlatSsvdag& s) {
  char line[256];
  std::snprintf(line, sizeof line,
                "%u^3: %llu voxels, %llu SSVDAG bytes (%.3f bits/voxel), %.3fx the DAG's %llu",
                grid.resolution, (unsigned long long)s.voxel_count,
                (unsigned long long)s.ssvdag_bytes,
                double(s.ssvdag_bytes) * 8.0 / double(s.voxel_count),
                double(s.ssvdag_bytes) / double(s.dag_bytes), (unsigned long long)s.dag_bytes);
  return line;
}

// The description, given the blob's indices of the sections (nodes, leaves).
auto describe_with(std::shared_ptr<const SsvdagStorage> storage, bool solid) {
  return
      [storage, solid](flatbuffers::FlatBufferBuilder& fbb, std::span<const std::uint32_t> index) {
        const FlatSsvdag& s = storage->ssvdag;
        const VoxelGrid& grid = storage->grid;
        std::vector<flatbuffers::Offset<schema::SsvdagLevel>> level_tables;
        for (const auto& l : s.level_stats)
          level_tables.push_back(schema::CreateSsvdagLevel(
              fbb, l.svo_nodes, l.dag_nodes, l.ssvdag_nodes, l.bytes, l.first_word, l.wide_pointers,
              l.narrow_pointers, l.relative_pointers));
        const double bits_per_voxel = double(s.ssvdag_bytes) * 8.0 / double(s.voxel_count);
        const auto desc = schema::CreateSsvdagDescDirect(
            fbb, grid.resolution, s.levels, grid.origin[0], grid.origin[1], grid.origin[2],
            grid.voxel_size, index[0], index[1], s.words.size(), s.leaves.size(), s.root_mirror,
            s.voxel_count, &level_tables, s.svo_bytes, s.dag_bytes, s.ssvdag_bytes, bits_per_voxel,
            s.symmetry_merges, solid);
        return std::pair{std::uint8_t(schema::StructureDesc::SsvdagDesc), desc.o};
      };
}

BuiltStructure build(const Scene& scene, const StructureRequest& request, unsigned threads) {
  VoxelizeOptions options;
  options.resolution = request.uint_option("resolution");
  options.solid = request.switch_option("solid");
  options.threads = threads;
  auto storage = std::make_shared<SsvdagStorage>();
  if (options.solid && options.resolution > format::kVoxelInCoreMaxResolution)
    throw std::invalid_argument("--accel ssvdag: --solid works in core, up to --resolution " +
                                std::to_string(format::kVoxelInCoreMaxResolution));
  if (options.solid) {
    // The solid fill needs every surface voxel at once.
    Voxels voxels = voxelize_surface(scene, options);
    storage->grid = voxels.grid;
    storage->ssvdag = build_ssvdag(solid_leaves(scene, voxels.grid, voxels.codes, threads),
                                   options.resolution, threads);
  } else {
    // The DAG's out-of-core build under the budget, then its unique nodes reduced by symmetry.
    if (!format::is_valid_voxel_resolution(options.resolution, format::kVoxelMaxResolution))
      throw std::invalid_argument("--resolution " + std::to_string(options.resolution) +
                                  " is outside the SSVDAG's range");
    storage->grid = fit_voxel_grid(scene.bounds, options.resolution);
    OutOfCoreDagOptions ooc;
    ooc.memory_budget = memory_budget_bytes(request.text_option("memory-budget"));
    ooc.threads = threads;
    ooc.progress = terminal_progress();
    storage->ssvdag = build_ssvdag(build_voxel_dag_out_of_core(scene, storage->grid, ooc), threads);
  }
  BuiltStructure built;
  built.sections = {raw_section(format::kSectionSsvdagNodes, storage->ssvdag.words),
                    raw_section(format::kSectionSsvdagLeaves, storage->ssvdag.leaves)};
  built.describe = describe_with(storage, options.solid);
  built.summary = summary_of(storage->grid, storage->ssvdag);
  built.storage = std::move(storage);
  return built;
}

}  // namespace

const StructureBuilder kSsvdagBuilder{"ssvdag",
                                      "Symmetry-aware sparse voxel DAG (Villanueva et al. 2016)",
                                      InputKind::kTriangles,
                                      ssvdag_options(),
                                      build,
                                      /*advise_variants=*/{},
                                      /*advise_skip=*/true};

}  // namespace kiln
