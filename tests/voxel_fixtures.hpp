// What the voxel tests share: a DAG built in memory with its view, and a one-structure blob.
#pragma once

#include <cstdint>
#include <string_view>
#include <vector>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/voxel_dag_builder.hpp"
#include "kiln/compiler/voxelizer.hpp"
#include "kiln/runtime/voxel_dag.hpp"
#include "test_support.hpp"

namespace kiln::test {

// The surface voxels (with normals) and their DAG.
struct BuiltDag {
  Voxels voxels;
  FlatVoxelDag dag;
  std::vector<std::uint64_t> firsts;
  VoxelDagView view() const {
    return VoxelDagView(dag.words, frame_of(voxels.grid), firsts, dag.leaf_first_word, voxels.codes,
                        voxels.normals);
  }
};

inline BuiltDag build_dag(const Scene& scene, std::uint32_t resolution) {
  BuiltDag b;
  b.voxels = voxelize_surface(scene, {resolution, true, 2});
  b.dag = build_voxel_dag(b.voxels.codes, resolution);
  b.firsts = level_first_words(b.dag);
  return b;
}

}  // namespace kiln::test
