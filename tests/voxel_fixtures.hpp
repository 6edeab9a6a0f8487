// What the voxel tests share: small scenes, a DAG built in memory with its view, brute-force
// references, and a one-structure blob.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string_view>
#include <utility>
#include <vector>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/scene.hpp"
#include "kiln/compiler/voxel_dag_builder.hpp"
#include "kiln/compiler/voxelizer.hpp"
#include "kiln/runtime/voxel_dag.hpp"
#include "test_support.hpp"

namespace kiln::test {

// A scene of the given triangles (one generated mesh).
inline Scene scene_of(std::vector<format::Float3> positions,
                      std::vector<format::Triangle> triangles) {
  Scene scene;
  scene.positions = std::move(positions);
  scene.triangles = std::move(triangles);
  scene.triangle_mesh.assign(scene.triangles.size(), 0);
  scene.input_triangle_count = scene.triangles.size();
  scene.bounds = bounds_of(scene.positions);
  scene.sources.push_back({"generated", 0, 0});
  scene.meshes.push_back({"generated", 0, 0, scene.triangles.size(), 0, scene.positions.size()});
  return scene;
}

// Long thin slivers along x and z (a diagonal one would make today's voxelizer test its whole
// bounding box): few voxels at any resolution, the grid [0, 1]^3.
inline Scene slivers() {
  return scene_of({{0, 0, 0},
                   {1, 0, 0},
                   {1, 0.00001f, 0},
                   {0.5f, 0.5f, 0},
                   {0.5f, 0.5f, 1},
                   {0.50001f, 0.5f, 1},
                   {1, 1, 1},
                   {0.99999f, 1, 1},
                   {1, 0.99999f, 1}},
                  {{{0, 1, 2}}, {{3, 4, 5}}, {{6, 7, 8}}});
}

// A triangle of the scene in grid units.
inline GridTriangle grid_triangle(const Scene& scene, const VoxelGrid& grid, std::size_t i) {
  const auto& tri = scene.triangles[i];
  return to_grid(grid, scene.positions[tri.v[0]], scene.positions[tri.v[1]],
                 scene.positions[tri.v[2]]);
}

// Which voxels the brute force visits per triangle. kWholeGrid: all N^3 voxels. kBoxPlus2: the
// voxels whose index lies in [floor(min) - 2, floor(max) + 2] of the triangle's grid-space
// bounding box on every axis, clipped to the grid (to stay fast at 64^3 .. 16384^3). A voxel
// outside that range is two voxels or more away from the triangle's box, so the box-axis tests
// alone reject it: both sweeps give the same set (checked on corpus meshes at 16^3). Neither uses
// the voxelizer's brick binning, candidate range or column walk.
enum class Sweep { kWholeGrid, kBoxPlus2 };

// Every (voxel code, triangle) pair with triangle_touches_voxel, sorted; only voxels of
// `within` when given (a cube of a grid too large to sweep).
inline std::vector<std::pair<std::uint64_t, std::uint32_t>> brute_force_hits(
    const Scene& scene, const VoxelGrid& grid, Sweep sweep, const VoxelCube* within = nullptr) {
  std::int64_t first[3], last[3];
  for (int a = 0; a < 3; ++a) {
    first[a] = within ? std::int64_t(within->origin[a]) : 0;
    last[a] = within ? first[a] + within->side - 1 : std::int64_t(grid.resolution) - 1;
  }
  std::vector<std::pair<std::uint64_t, std::uint32_t>> hits;
  for (std::uint32_t i = 0; i < scene.triangles.size(); ++i) {
    const GridTriangle t = grid_triangle(scene, grid, i);
    std::int64_t lo[3] = {first[0], first[1], first[2]}, hi[3] = {last[0], last[1], last[2]};
    if (sweep == Sweep::kBoxPlus2)
      for (int a = 0; a < 3; ++a) {
        const double mn =
            std::min({format::at(t.v[0], a), format::at(t.v[1], a), format::at(t.v[2], a)});
        const double mx =
            std::max({format::at(t.v[0], a), format::at(t.v[1], a), format::at(t.v[2], a)});
        lo[a] = std::max<std::int64_t>(first[a], std::int64_t(std::floor(mn)) - 2);
        hi[a] = std::min<std::int64_t>(last[a], std::int64_t(std::floor(mx)) + 2);
      }
    for (std::int64_t z = lo[2]; z <= hi[2]; ++z)
      for (std::int64_t y = lo[1]; y <= hi[1]; ++y)
        for (std::int64_t x = lo[0]; x <= hi[0]; ++x)
          if (triangle_touches_voxel(t, std::uint32_t(x), std::uint32_t(y), std::uint32_t(z)))
            hits.emplace_back(
                format::morton_code(std::uint32_t(x), std::uint32_t(y), std::uint32_t(z)), i);
  }
  std::sort(hits.begin(), hits.end());
  return hits;
}

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
