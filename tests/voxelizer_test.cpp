// The voxelizer against brute force (every voxel of the grid against every triangle, with the
// same exact predicate) on corpus meshes and generated worst cases; the DAG against the voxel
// set it was built from.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/voxel_dag_builder.hpp"
#include "kiln/compiler/voxelizer.hpp"
#include "kiln/formats/voxel_grid.hpp"
#include "test_support.hpp"
#include "voxel_fixtures.hpp"

namespace kiln {
namespace {

using format::Float3;

// Every voxel of the grid tested against every triangle: no binning, no column walk.
std::vector<std::uint64_t> brute_force_voxels(const Scene& scene, const VoxelGrid& grid) {
  std::vector<std::uint64_t> codes;
  const std::uint32_t n = grid.resolution;
  for (const auto& tri : scene.triangles) {
    const GridTriangle t = to_grid(grid, scene.positions[tri.v[0]], scene.positions[tri.v[1]],
                                   scene.positions[tri.v[2]]);
    for (std::uint32_t z = 0; z < n; ++z)
      for (std::uint32_t y = 0; y < n; ++y)
        for (std::uint32_t x = 0; x < n; ++x)
          if (triangle_touches_voxel(t, x, y, z)) codes.push_back(format::morton_code(x, y, z));
  }
  std::sort(codes.begin(), codes.end());
  codes.erase(std::unique(codes.begin(), codes.end()), codes.end());
  return codes;
}

Scene triangles_scene(const std::vector<std::array<Float3, 3>>& triangles) {
  Scene scene;
  for (const auto& t : triangles) {
    const auto base = std::uint32_t(scene.positions.size());
    scene.positions.insert(scene.positions.end(), t.begin(), t.end());
    scene.triangles.push_back({{base, base + 1, base + 2}});
    scene.triangle_mesh.push_back(0);
  }
  scene.bounds = bounds_of(scene.positions);
  scene.sources.push_back({"generated", 0, 0});
  scene.meshes.push_back({"generated", 0, 0, scene.triangles.size(), 0, scene.positions.size()});
  return scene;
}

void expect_matches_brute_force(const Scene& scene, std::uint32_t n, const std::string& what) {
  const Voxels voxels = voxelize_surface(scene, {n, false, 2});
  ASSERT_FALSE(voxels.codes.empty()) << what;
  EXPECT_LT(voxels.codes.back(), std::uint64_t(n) * n * n);
  EXPECT_EQ(voxels.codes, brute_force_voxels(scene, voxels.grid)) << what << " at " << n;
  // The grid holds the bounds.
  const float lo[3] = {scene.bounds.min.x, scene.bounds.min.y, scene.bounds.min.z};
  const float hi[3] = {scene.bounds.max.x, scene.bounds.max.y, scene.bounds.max.z};
  for (int a = 0; a < 3; ++a) {
    EXPECT_LE(voxels.grid.origin[a], lo[a]);
    EXPECT_GE(voxels.grid.origin[a] + n * voxels.grid.voxel_size, hi[a]);
  }
}

TEST(Voxelizer, MatchesBruteForceOnCorpusMeshes) {
  KILN_REQUIRE_CORPUS();
  for (const auto& [mesh, resolutions] :
       std::vector<std::pair<const char*, std::vector<std::uint32_t>>>{
           {"assimp/OBJ/spider.obj", {8, 16, 32}},
           {"classic/spot.obj", {16, 32}},
           {"classic/fandisk.obj", {16}},
           {"assimp/OBJ/box.obj", {8, 16}}}) {
    const Scene scene = import_scene({test::mesh_path(mesh)}, 2);
    for (const auto n : resolutions) expect_matches_brute_force(scene, n, mesh);
  }
}

TEST(Voxelizer, MatchesBruteForceOnWorstCases) {
  // On grid planes (the grid is [0, 8]^3 for these), on voxel faces and edges, slivers, a huge
  // slanted triangle, tiny ones inside one voxel, and triangles on the grid's outer faces.
  const std::vector<std::array<Float3, 3>> cases = {
      {{{0, 0, 0}, {8, 0, 0}, {0, 8, 8}}},  // the grid's diagonal slab
      {{{1, 1, 2}, {5, 1, 2}, {1, 5, 2}}},  // exactly in the plane z = 2
      {{{2, 3, 0}, {2, 7, 8}, {2, 3, 8}}},  // exactly in the plane x = 2
      {{{0.1f, 0.1f, 0.1f}, {7.9f, 7.9f, 7.9f}, {7.9f, 7.9f, 7.90001f}}},  // sliver
      {{{3.2f, 3.2f, 3.2f}, {3.3f, 3.2f, 3.2f}, {3.2f, 3.3f, 3.25f}}},     // inside one voxel
      {{{8, 0, 0}, {8, 8, 0}, {8, 0, 8}}},                                 // on the grid's max face
      {{{4, 4, 4}, {6, 4, 4}, {4, 4.000001f, 6}}},                         // nearly edge-on
  };
  const Scene all = triangles_scene(cases);
  for (const std::uint32_t n : {8u, 16u, 32u}) expect_matches_brute_force(all, n, "worst cases");
  for (std::size_t i = 0; i < cases.size(); ++i) {
    std::vector<std::array<Float3, 3>> one = {cases[i]};
    one.push_back({{{0, 0, 0}, {8, 0, 0}, {0, 8, 8}}});  // fix the grid to [0, 8]^3
    expect_matches_brute_force(triangles_scene(one), 8, "case " + std::to_string(i));
  }
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> unit(-1, 1);
  std::vector<std::array<Float3, 3>> random;
  for (int i = 0; i < 60; ++i)
    random.push_back({{{unit(rng), unit(rng), unit(rng)},
                       {unit(rng), unit(rng), unit(rng)},
                       {unit(rng), unit(rng), unit(rng)}}});
  expect_matches_brute_force(triangles_scene(random), 16, "random");
}

TEST(Voxelizer, RefusesBadResolutions) {
  const Scene scene = triangles_scene({{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}}});
  for (const std::uint32_t n : {0u, 3u, 4u, 100u, format::kVoxelMaxResolution * 2})
    EXPECT_THROW(voxelize_surface(scene, {n, false, 1}), std::invalid_argument) << n;
}

// Cube by cube (as out-of-core builds go), in Morton order of the cubes, gives the whole grid's
// voxels, normals and 4x4x4 leaves; each cube holds only its own voxels.
TEST(Voxelizer, CubesConcatenateToTheWholeGrid) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({test::mesh_path("stanford/stanford-bunny.obj.zst")}, 2);
  const std::uint32_t n = 256;
  const Voxels whole = voxelize_surface(scene, {n, true, 2});
  for (const std::uint32_t side : {32u, 64u, 256u}) {
    Voxels joined;
    VoxelLeaves leaves;
    const std::uint32_t per_axis = n / side;
    for (std::uint64_t c = 0; c < std::uint64_t(per_axis) * per_axis * per_axis; ++c) {
      const VoxelCube cube{{format::compact_bits(c) * side, format::compact_bits(c >> 1) * side,
                            format::compact_bits(c >> 2) * side},
                           side};
      const std::vector<std::uint32_t> tris = triangles_reaching(scene, whole.grid, cube);
      const Voxels part = voxelize_surface_cube(scene, whole.grid, cube, tris, true, 2);
      for (const std::uint64_t code : part.codes) {
        const std::uint32_t x = format::compact_bits(code), y = format::compact_bits(code >> 1),
                            z = format::compact_bits(code >> 2);
        ASSERT_TRUE(x / side * side == cube.origin[0] && y / side * side == cube.origin[1] &&
                    z / side * side == cube.origin[2]);
      }
      joined.codes.insert(joined.codes.end(), part.codes.begin(), part.codes.end());
      joined.normals.insert(joined.normals.end(), part.normals.begin(), part.normals.end());
      const VoxelLeaves l = voxelize_surface_leaves(scene, whole.grid, cube, tris, 2);
      leaves.keys.insert(leaves.keys.end(), l.keys.begin(), l.keys.end());
      leaves.masks.insert(leaves.masks.end(), l.masks.begin(), l.masks.end());
      leaves.voxel_count += l.voxel_count;
    }
    EXPECT_EQ(joined.codes, whole.codes) << side;
    EXPECT_EQ(joined.normals, whole.normals) << side;
    const VoxelLeaves expected = leaves_of(whole.codes);
    EXPECT_EQ(leaves.keys, expected.keys) << side;
    EXPECT_EQ(leaves.masks, expected.masks) << side;
    EXPECT_EQ(leaves.voxel_count, expected.voxel_count) << side;
  }
}

TEST(Voxelizer, RefusesCubesOutsideTheGrid) {
  const Scene scene = triangles_scene({{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}}});
  const VoxelGrid grid = fit_voxel_grid(scene.bounds, 64);
  const std::uint32_t none[] = {0};
  for (const VoxelCube& cube :
       {VoxelCube{{0, 0, 0}, 2}, VoxelCube{{0, 0, 0}, 48}, VoxelCube{{8, 0, 0}, 16},
        VoxelCube{{64, 0, 0}, 16}, VoxelCube{{0, 0, 0}, 128}})
    EXPECT_THROW(voxelize_surface_cube(scene, grid, cube, none, false, 1), std::invalid_argument);
  EXPECT_NO_THROW(voxelize_surface_cube(scene, grid, VoxelCube{{48, 16, 0}, 16}, none, false, 1));
}

TEST(Voxelizer, NormalsAreDeterministicAndUnit) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({test::mesh_path("stanford/stanford-bunny.obj.zst")}, 2);
  const Voxels one = voxelize_surface(scene, {256, true, 1});
  for (const unsigned threads : {2u, 8u}) {
    const Voxels other = voxelize_surface(scene, {256, true, threads});
    EXPECT_EQ(one.codes, other.codes);
    EXPECT_EQ(one.normals, other.normals);
  }
  ASSERT_EQ(one.normals.size(), one.codes.size());
  for (const auto bits : one.normals) {
    float n[3];
    format::decode_octahedral(bits, n);
    EXPECT_NEAR(n[0] * n[0] + n[1] * n[1] + n[2] * n[2], 1.0f, 1e-4f);
  }
  // A flat square facing +z: every voxel's normal is +z.
  const Scene flat =
      triangles_scene({{{{0, 0, 1}, {4, 0, 1}, {4, 4, 1}}}, {{{0, 0, 1}, {4, 4, 1}, {0, 4, 1}}}});
  const Voxels v = voxelize_surface(flat, {32, true, 2});
  for (const auto bits : v.normals) {
    float n[3];
    format::decode_octahedral(bits, n);
    EXPECT_NEAR(n[2], 1.0f, 1e-3f);
  }
}

// Reference for the fast paths: per triangle, every voxel of its bounding box (the predicate's
// box-axis tests reject every other voxel) against triangle_touches_voxel, as (code, triangle)
// pairs sorted, and the normals summed per voxel in that order as the voxelizer documents.
Voxels reference_voxels(const Scene& scene, const VoxelGrid& grid, bool normals) {
  const auto hits = test::brute_force_hits(scene, grid, test::Sweep::kBoxPlus2);
  Voxels out;
  out.grid = grid;
  for (std::size_t k = 0; k < hits.size();) {
    double sum[3] = {0, 0, 0};
    std::size_t end = k;
    for (; end < hits.size() && hits[end].first == hits[k].first; ++end) {
      const auto& tri = scene.triangles[hits[end].second];
      const format::Double3 a = to_d(scene.positions[tri.v[0]]),
                            b = to_d(scene.positions[tri.v[1]]),
                            c = to_d(scene.positions[tri.v[2]]);
      const format::Double3 nrm = cross(b - a, c - a);
      const double length = std::sqrt(dot(nrm, nrm));
      for (int axis = 0; axis < 3; ++axis) sum[axis] += format::at(nrm, axis) / length;
    }
    out.codes.push_back(hits[k].first);
    if (normals)
      out.normals.push_back(format::encode_octahedral(float(sum[0]), float(sum[1]), float(sum[2])));
    k = end;
  }
  return out;
}

std::vector<std::uint32_t> all_triangles(const Scene& scene) {
  std::vector<std::uint32_t> all(scene.triangles.size());
  for (std::uint32_t i = 0; i < all.size(); ++i) all[i] = i;
  return all;
}

void expect_leaves_equal(const VoxelLeaves& got, const VoxelLeaves& want, const std::string& what) {
  EXPECT_EQ(got.keys, want.keys) << what;
  EXPECT_EQ(got.masks, want.masks) << what;
  EXPECT_EQ(got.voxel_count, want.voxel_count) << what;
}

// The whole grid through every path (leaves, codes, codes with normals) against the reference.
void expect_paths_match_reference(const Scene& scene, const VoxelGrid& grid,
                                  const std::string& what) {
  const Voxels want = reference_voxels(scene, grid, true);
  const std::vector<std::uint32_t> all = all_triangles(scene);
  const VoxelCube cube{{0, 0, 0}, grid.resolution};
  expect_leaves_equal(voxelize_surface_leaves(scene, grid, cube, all, 2), leaves_of(want.codes),
                      what);
  EXPECT_EQ(voxelize_surface_cube(scene, grid, cube, all, false, 2).codes, want.codes) << what;
  const Voxels with_normals = voxelize_surface_cube(scene, grid, cube, all, true, 2);
  EXPECT_EQ(with_normals.codes, want.codes) << what;
  EXPECT_EQ(with_normals.normals, want.normals) << what;
}

// Leaves, codes and normals equal the reference on corpus meshes at several resolutions.
TEST(Voxelizer, FastPathsMatchReferenceOnCorpusMeshes) {
  KILN_REQUIRE_CORPUS();
  for (const auto& [mesh, resolutions] :
       std::vector<std::pair<const char*, std::vector<std::uint32_t>>>{
           {"stanford/stanford-bunny.obj.zst", {64, 256}},
           {"assimp/OBJ/spider.obj", {32, 128}},
           {"classic/fandisk.obj", {64}},
           {"assimp/OBJ/box.obj", {16, 64}}}) {
    const Scene scene = import_scene({test::mesh_path(mesh)}, 2);
    for (const auto n : resolutions)
      expect_paths_match_reference(scene, fit_voxel_grid(scene.bounds, n),
                                   std::string(mesh) + " at " + std::to_string(n));
  }
}

// Triangles given in grid units on a unit grid (origin 0, voxel size 1), where the decision
// boundaries fall exactly on voxel faces, edges and corners.
Scene grid_unit_scene(const std::vector<std::array<Float3, 3>>& triangles) {
  return triangles_scene(triangles);
}
VoxelGrid unit_grid(std::uint32_t n) {
  return VoxelGrid{{0, 0, 0}, 1.0, n};
}

std::vector<std::array<Float3, 3>> worst_case_triangles(std::uint32_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  const float top = float(n);
  auto pick = [&](int kind) -> float {
    std::uniform_real_distribution<float> any(0, top);
    switch (kind) {
      case 0:
        return float(std::uniform_int_distribution<int>(0, int(n))(rng));  // on a face
      case 1:
        return float(std::uniform_int_distribution<int>(0, int(2 * n))(rng)) / 2;  // centre
      case 2:
        return std::nextafter(float(std::uniform_int_distribution<int>(1, int(n) - 1)(rng)),
                              (rng() & 1) ? 0.0f : top);  // one ulp off a face
      default:
        return any(rng);
    }
  };
  std::vector<std::array<Float3, 3>> out;
  for (int i = 0; i < 400; ++i) {
    const int kind = int(rng() % 5);
    Float3 p[3];
    for (auto& q : p) q = {pick(int(rng() % 4)), pick(int(rng() % 4)), pick(int(rng() % 4))};
    if (kind == 1) {  // axis-aligned: one coordinate shared
      const int a = int(rng() % 3);
      for (auto& q : p) format::at(q, a) = format::at(p[0], a);
    } else if (kind == 2) {  // sliver: the third corner near the first edge
      const float t = std::uniform_real_distribution<float>(0, 1)(rng);
      for (int a = 0; a < 3; ++a)
        format::at(p[2], a) = format::at(p[0], a) + (format::at(p[1], a) - format::at(p[0], a)) * t;
      format::at(p[2], int(rng() % 3)) += (rng() & 1) ? 1e-4f : 0.0f;
    } else if (kind == 3) {  // tiny, inside or across a voxel
      const float s = (rng() & 1) ? 1e-3f : 0.3f;
      p[1] = {p[0].x + s, p[0].y, p[0].z + s / 2}, p[2] = {p[0].x, p[0].y + s, p[0].z + s};
    } else if (kind == 4 && (rng() & 1)) {  // degenerate: a repeated corner
      p[2] = p[1];
    }
    for (auto& q : p)
      for (int a = 0; a < 3; ++a) format::at(q, a) = std::clamp(format::at(q, a), 0.0f, top);
    out.push_back({p[0], p[1], p[2]});
  }
  // Huge ones: the grid's diagonals and a face.
  out.push_back({{{0, 0, 0}, {top, top, 0}, {0, top, top}}});
  out.push_back({{{0, 0, 0}, {top, 0, 0}, {top, top, top}}});
  out.push_back({{{0, 0, top}, {top, 0, top}, {0, top, top}}});
  return out;
}

TEST(Voxelizer, FastPathsMatchReferenceOnWorstCases) {
  for (const std::uint32_t n : {8u, 16u, 64u}) {
    const auto triangles = worst_case_triangles(n, n);
    // One triangle at a time (a wrong voxel is then easy to find), then all together.
    for (std::size_t i = 0; i < triangles.size(); i += 7)
      expect_paths_match_reference(grid_unit_scene({triangles[i]}), unit_grid(n),
                                   "triangle " + std::to_string(i) + " at " + std::to_string(n));
    expect_paths_match_reference(grid_unit_scene(triangles), unit_grid(n),
                                 "all at " + std::to_string(n));
  }
  // Scaled grids (voxel size not 1, origin off zero): rounding in to_grid.
  auto triangles = worst_case_triangles(16, 99);
  triangles.resize(120);
  const Scene scene = grid_unit_scene(triangles);
  for (const std::uint32_t n : {32u, 128u})
    expect_paths_match_reference(scene, fit_voxel_grid(scene.bounds, n),
                                 "fitted at " + std::to_string(n));
}

// Small triangles with corners on a 1/8-voxel lattice (as quantized meshes such as Draco's give:
// many edges parallel to a grid plane), 1 to 9 voxels wide, at every offset from the 4x4x4
// leaves, some across the 128^3 bricks, in a 256^3 unit grid.
std::vector<std::array<Float3, 3>> small_quantized_triangles(std::uint32_t seed, int count) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> corner(0, 8 * 240), size(-8 * 9, 8 * 9);
  std::vector<std::array<Float3, 3>> triangles;
  for (int i = 0; i < count; ++i) {
    Float3 p[3];
    p[0] = {float(corner(rng)) / 8, float(corner(rng)) / 8, float(corner(rng)) / 8};
    if (i % 3 == 0)  // across a brick boundary
      format::at(p[0], int(rng() % 3)) = 128 + float(size(rng)) / 32;
    for (int j = 1; j < 3; ++j)
      p[j] = {p[0].x + float(size(rng) * (i % 4 + 1) / 4) / 8,
              p[0].y + float(size(rng) * (i % 4 + 1) / 4) / 8,
              p[0].z + float(size(rng) * (i % 4 + 1) / 4) / 8};
    if (i % 5 == 0) p[2].z = p[1].z = p[0].z;          // in a plane z = const
    if (i % 7 == 0) p[1].x = p[0].x, p[2].y = p[0].y;  // edges parallel to grid planes
    for (auto& q : p)
      for (int a = 0; a < 3; ++a) format::at(q, a) = std::clamp(format::at(q, a), 0.0f, 256.0f);
    triangles.push_back({p[0], p[1], p[2]});
  }
  return triangles;
}

// The window walk, its merged tests and its leaf masks.
TEST(Voxelizer, FastPathsMatchReferenceOnSmallQuantizedTriangles) {
  expect_paths_match_reference(grid_unit_scene(small_quantized_triangles(871, 1500)),
                               unit_grid(256), "small quantized");
}

// The voxels of `cube` the triangles touch (codes, ascending, once each), by brute force.
std::vector<std::uint64_t> cube_reference(const Scene& scene, const VoxelGrid& grid,
                                          const VoxelCube& cube) {
  std::vector<std::uint64_t> want;
  for (const auto& hit : test::brute_force_hits(scene, grid, test::Sweep::kBoxPlus2, &cube))
    if (want.empty() || want.back() != hit.first) want.push_back(hit.first);
  return want;
}

// Small triangles at the far corner of the largest grid (grid coordinates near 2^17, where a
// float position's ulp is 2^-6): corners on the 1/64 lattice, on voxel faces and one ulp off
// them, slivers and repeated corners, in a 64^3 sub-cube.
std::vector<std::array<Float3, 3>> far_corner_triangles(float base, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> at(-4 * 64, 68 * 64), size(-64 * 6, 64 * 6);
  std::vector<std::array<Float3, 3>> out;
  for (int i = 0; i < 300; ++i) {
    Float3 p[3];
    for (int j = 0; j < 3; ++j)
      for (int a = 0; a < 3; ++a)
        format::at(p[j], a) =
            j == 0 ? base + float(at(rng)) / 64 : format::at(p[0], a) + float(size(rng)) / 64;
    if (i % 4 == 1)  // on voxel faces (integers), or one ulp off
      for (auto& q : p) {
        const int a = int(rng() % 3);
        format::at(q, a) = std::round(format::at(q, a));
        if (rng() & 1) format::at(q, a) = std::nextafter(format::at(q, a), 0.0f);
      }
    if (i % 6 == 2) p[2] = p[1];                                  // degenerate
    if (i % 6 == 3) p[2] = {p[0].x, p[0].y, p[0].z + 1.0f / 64};  // sliver
    if (i % 5 == 4) p[1].z = p[2].z = p[0].z;                     // axis-aligned plane
    out.push_back({p[0], p[1], p[2]});
  }
  return out;
}

// Every small-triangle kernel the CPU runs (the column walk, the AVX2 and AVX-512 window
// kernels), forced one after the other, against the predicate voxel by voxel on adversarial
// triangles: the worst cases (faces, centres, ulps off faces, slivers, degenerate, axis-aligned),
// small quantized ones at every leaf offset and across bricks, and small ones at the far corner of
// the 131072^3 grid.
TEST(Voxelizer, EveryKernelMatchesPredicateOnAdversarialTriangles) {
  const Scene worst = grid_unit_scene(worst_case_triangles(16, 1620));
  const Scene small = grid_unit_scene(small_quantized_triangles(4096, 1200));
  constexpr std::uint32_t kMax = 131072;
  const Scene far = triangles_scene(far_corner_triangles(float(kMax - 64), 7));
  const VoxelCube far_cube{{kMax - 64, kMax - 64, kMax - 64}, 64};
  const std::vector<std::uint64_t> far_want = cube_reference(far, unit_grid(kMax), far_cube);
  ASSERT_GT(far_want.size(), 1000u);
  for (const VoxelKernel kernel :
       {VoxelKernel::kColumns, VoxelKernel::kAvx2, VoxelKernel::kAvx512}) {
    const std::string name = voxel_kernel_name(kernel);
    if (!voxel_kernel_supported(kernel)) {
      std::printf("[ SKIPPED  ] kernel %s: this CPU cannot run it\n", name.c_str());
      continue;
    }
    set_voxel_kernel(kernel);
    ASSERT_EQ(voxel_kernel(), kernel);
    expect_paths_match_reference(worst, unit_grid(16), name + ": worst cases");
    expect_paths_match_reference(small, unit_grid(256), name + ": small quantized");
    const std::vector<std::uint32_t> all = all_triangles(far);
    expect_leaves_equal(voxelize_surface_leaves(far, unit_grid(kMax), far_cube, all, 2),
                        leaves_of(far_want), name + ": far corner");
    EXPECT_EQ(voxelize_surface_cube(far, unit_grid(kMax), far_cube, all, true, 2).codes, far_want)
        << name;
  }
  set_voxel_kernel(VoxelKernel::kAuto);
}

// An indexed mesh of small triangles (a wavy sheet on a 1/8-voxel lattice, vertices shared):
// the whole mesh converts each vertex once, a small subset of its triangles (fewer than half the
// vertices) converts each triangle's corners; both against the predicate, whatever span of
// leaves along the dominant axis each triangle's window has.
TEST(Voxelizer, SharedVertexMeshMatchesReferenceWholeAndSubset) {
  std::mt19937 rng(2026);
  std::uniform_int_distribution<int> jitter(-6, 6);
  constexpr int kSide = 48;
  Scene mesh;
  for (int j = 0; j <= kSide; ++j)
    for (int i = 0; i <= kSide; ++i) {
      const float h = 64 + 24 * std::sin(float(i) * 0.31f) * std::cos(float(j) * 0.17f);
      mesh.positions.push_back({float(8 * 40 + 8 * 3 * i + jitter(rng)) / 8,
                                float(8 * 40 + 8 * 3 * j + jitter(rng)) / 8,
                                std::round(h * 8 + float(jitter(rng))) / 8});
    }
  for (std::uint32_t j = 0; j < kSide; ++j)
    for (std::uint32_t i = 0; i < kSide; ++i) {
      const std::uint32_t a = j * (kSide + 1) + i, b = a + 1, c = a + kSide + 1, d = c + 1;
      mesh.triangles.push_back({{a, b, d}}), mesh.triangles.push_back({{a, d, c}});
      mesh.triangle_mesh.push_back(0), mesh.triangle_mesh.push_back(0);
    }
  mesh.bounds = bounds_of(mesh.positions);
  mesh.sources.push_back({"generated", 0, 0});
  mesh.meshes.push_back({"generated", 0, 0, mesh.triangles.size(), 0, mesh.positions.size()});
  const VoxelGrid grid = unit_grid(256);
  expect_paths_match_reference(mesh, grid, "shared-vertex sheet");
  Scene subset = mesh;  // every 9th triangle: 512 triangles for 2401 vertices
  subset.triangles.clear(), subset.triangle_mesh.clear();
  std::vector<std::uint32_t> picked;
  for (std::uint32_t t = 0; t < mesh.triangles.size(); t += 9)
    picked.push_back(t), subset.triangles.push_back(mesh.triangles[t]),
        subset.triangle_mesh.push_back(0);
  subset.meshes[0].triangle_count = subset.triangles.size();
  ASSERT_LT(2 * picked.size(), mesh.positions.size());
  const VoxelCube cube{{0, 0, 0}, grid.resolution};
  expect_leaves_equal(voxelize_surface_leaves(mesh, grid, cube, picked, 2),
                      leaves_of(reference_voxels(subset, grid, false).codes), "subset");
}

// Huge triangles on grids up to 131072^3 (the margins grow with the triangle's extent): one
// sub-cube through each path against every voxel of the cube under the predicate.
TEST(Voxelizer, FastPathsMatchPredicateOnHugeTrianglesInSubCubes) {
  std::mt19937 rng(20);
  for (const std::uint32_t n : {4096u, 131072u}) {
    const VoxelGrid grid = unit_grid(n);
    const VoxelCube cube{{n / 2 - 32, n / 4, n / 2}, 32};
    std::vector<std::array<Float3, 3>> triangles;
    std::uniform_int_distribution<std::uint32_t> any(0, n), near(0, 64);
    for (int i = 0; i < 40; ++i) {
      // Two far corners and one near the cube (integer or half coordinates: boundary cases).
      Float3 p[3];
      for (int j = 0; j < 2; ++j) p[j] = {float(any(rng)), float(any(rng)), float(any(rng))};
      p[2] = {float(cube.origin[0] - 16 + near(rng)) + 0.5f * float(rng() & 1),
              float(cube.origin[1] - 16 + near(rng)), float(cube.origin[2] - 16 + near(rng))};
      triangles.push_back({p[0], p[1], p[2]});
    }
    triangles.push_back({{{0, 0, float(cube.origin[2] + 3)},
                          {float(n), 0, float(cube.origin[2] + 3)},
                          {0, float(n), float(cube.origin[2] + 3)}}});  // on a voxel face
    const Scene scene = triangles_scene(triangles);
    std::vector<std::uint64_t> want;
    for (const auto& tri : scene.triangles) {
      const GridTriangle t = to_grid(grid, scene.positions[tri.v[0]], scene.positions[tri.v[1]],
                                     scene.positions[tri.v[2]]);
      for (std::uint32_t z = cube.origin[2]; z < cube.origin[2] + cube.side; ++z)
        for (std::uint32_t y = cube.origin[1]; y < cube.origin[1] + cube.side; ++y)
          for (std::uint32_t x = cube.origin[0]; x < cube.origin[0] + cube.side; ++x)
            if (triangle_touches_voxel(t, x, y, z)) want.push_back(format::morton_code(x, y, z));
    }
    std::sort(want.begin(), want.end());
    want.erase(std::unique(want.begin(), want.end()), want.end());
    ASSERT_FALSE(want.empty());
    const std::vector<std::uint32_t> all = all_triangles(scene);
    expect_leaves_equal(voxelize_surface_leaves(scene, grid, cube, all, 2), leaves_of(want),
                        "huge at " + std::to_string(n));
    EXPECT_EQ(voxelize_surface_cube(scene, grid, cube, all, true, 2).codes, want);
  }
}

TEST(Voxelizer, LeavesByteIdenticalAcrossThreadsAndCubes) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({test::mesh_path("classic/spot.obj")}, 2);
  const VoxelGrid grid = fit_voxel_grid(scene.bounds, 256);
  const std::vector<std::uint32_t> all = all_triangles(scene);
  const VoxelLeaves one = voxelize_surface_leaves(scene, grid, {{0, 0, 0}, 256}, all, 1);
  for (const unsigned threads : {2u, 8u})
    expect_leaves_equal(voxelize_surface_leaves(scene, grid, {{0, 0, 0}, 256}, all, threads), one,
                        std::to_string(threads) + " threads");
  // Sub-cubes smaller than a brick (4, 16) and as large (128), with triangles_reaching.
  for (const std::uint32_t side : {4u, 16u, 128u}) {
    VoxelLeaves joined;
    const std::uint32_t per_axis = 256 / side;
    std::uint64_t cubes_done = 0;
    for (std::uint64_t c = 0; c < std::uint64_t(per_axis) * per_axis * per_axis; ++c) {
      const VoxelCube cube{{format::compact_bits(c) * side, format::compact_bits(c >> 1) * side,
                            format::compact_bits(c >> 2) * side},
                           side};
      if (side == 4 && (c % 211) != 0) continue;  // a sample of the 262k small cubes
      ++cubes_done;
      const VoxelLeaves l =
          voxelize_surface_leaves(scene, grid, cube, triangles_reaching(scene, grid, cube), 2);
      if (side == 4) {  // compare with the whole grid's leaves in this cube
        const std::uint64_t key =
            format::morton_code(cube.origin[0], cube.origin[1], cube.origin[2]) >> 6;
        const auto it = std::lower_bound(one.keys.begin(), one.keys.end(), key);
        const bool present = it != one.keys.end() && *it == key;
        ASSERT_EQ(l.keys.size(), present ? 1u : 0u);
        if (present) {
          EXPECT_EQ(l.masks[0], one.masks[std::size_t(it - one.keys.begin())]);
        }
        continue;
      }
      joined.keys.insert(joined.keys.end(), l.keys.begin(), l.keys.end());
      joined.masks.insert(joined.masks.end(), l.masks.begin(), l.masks.end());
      joined.voxel_count += l.voxel_count;
    }
    if (side != 4) expect_leaves_equal(joined, one, "cubes of " + std::to_string(side));
    EXPECT_GT(cubes_done, 0u);
  }
}

// Enough triangles for the binning to split them into several fixed ranges (of 16k), given in a
// shuffled order, many crossing brick boundaries: with 1, 2 and 7 threads the leaves and the
// codes with normals (summed in ascending triangle order) equal the predicate's.
TEST(Voxelizer, BinningInRangesSameForAnyThreadCount) {
  std::mt19937 rng(20);
  std::uniform_int_distribution<int> corner(0, 8 * 255), step(-8, 8), big(-8 * 24, 8 * 24);
  std::vector<std::array<Float3, 3>> triangles;
  for (int i = 0; i < 40000; ++i) {
    Float3 p[3];
    p[0] = {float(corner(rng)) / 8, float(corner(rng)) / 8, float(corner(rng)) / 8};
    if (i % 4 == 0) format::at(p[0], i / 4 % 3) = 128 + float(step(rng)) / 8;  // at a brick face
    for (int j = 1; j < 3; ++j)
      for (int a = 0; a < 3; ++a)
        format::at(p[j], a) = std::clamp(
            format::at(p[0], a) + float(i % 500 == 0 ? big(rng) : step(rng)) / 8, 0.0f, 256.0f);
    triangles.push_back({p[0], p[1], p[2]});
  }
  const Scene scene = grid_unit_scene(triangles);
  const VoxelGrid grid = unit_grid(256);
  const Voxels want = reference_voxels(scene, grid, true);
  std::vector<std::uint32_t> order = all_triangles(scene);
  std::shuffle(order.begin(), order.end(), rng);
  const VoxelCube cube{{0, 0, 0}, 256};
  for (const unsigned threads : {1u, 2u, 7u}) {
    const std::string what = std::to_string(threads) + " threads";
    expect_leaves_equal(voxelize_surface_leaves(scene, grid, cube, order, threads),
                        leaves_of(want.codes), what);
    const Voxels got = voxelize_surface_cube(scene, grid, cube, order, true, threads);
    EXPECT_EQ(got.codes, want.codes) << what;
    EXPECT_EQ(got.normals, want.normals) << what;
  }
}

TEST(VoxelDag, ExpandsToExactlyTheVoxelSet) {
  std::vector<std::pair<std::string, std::pair<std::vector<std::uint64_t>, std::uint32_t>>> sets;
  sets.push_back({"one voxel", {{format::morton_code(5, 1, 7)}, 8}});
  std::vector<std::uint64_t> full8(512);
  for (std::uint64_t i = 0; i < 512; ++i) full8[i] = i;
  sets.push_back({"full 8^3", {full8, 8}});
  std::vector<std::uint64_t> checker;
  for (std::uint32_t z = 0; z < 16; ++z)
    for (std::uint32_t y = 0; y < 16; ++y)
      for (std::uint32_t x = 0; x < 16; ++x)
        if ((x + y + z) % 2 == 0) checker.push_back(format::morton_code(x, y, z));
  std::sort(checker.begin(), checker.end());
  sets.push_back({"checkerboard 16^3", {checker, 16}});
  std::mt19937_64 rng(8);
  std::vector<std::uint64_t> sparse;
  for (int i = 0; i < 3000; ++i) sparse.push_back(rng() % (std::uint64_t{1} << 24));
  std::sort(sparse.begin(), sparse.end());
  sparse.erase(std::unique(sparse.begin(), sparse.end()), sparse.end());
  sets.push_back({"random sparse 256^3", {sparse, 256}});
  if (test::corpus_present()) {
    const Scene bunny = import_scene({test::mesh_path("stanford/stanford-bunny.obj.zst")}, 2);
    sets.push_back({"bunny 256^3", {voxelize_surface(bunny, {256, false, 2}).codes, 256}});
  }
  for (const auto& [name, set] : sets) {
    const auto& [codes, n] = set;
    const FlatVoxelDag dag = build_voxel_dag(codes, n);
    EXPECT_EQ(expand_voxel_dag(dag.words, dag.levels), codes) << name;
    EXPECT_EQ(dag.voxel_count, codes.size());
    EXPECT_EQ(dag.level_stats[0].svo_nodes, 1u);
    std::uint64_t bytes = 0;
    for (const auto& l : dag.level_stats) {
      EXPECT_LE(l.dag_nodes, l.svo_nodes) << name;
      bytes += l.bytes;
    }
    EXPECT_EQ(bytes, dag.dag_bytes);
    EXPECT_EQ(dag.dag_bytes, 4 * dag.words.size());
    EXPECT_GE(dag.svo_bytes, dag.dag_bytes);
  }
  // Merging: a full grid and a checkerboard have one distinct node per level.
  for (const auto* codes : {&full8, &checker}) {
    const FlatVoxelDag dag = build_voxel_dag(*codes, codes == &full8 ? 8 : 16);
    for (const auto& l : dag.level_stats) EXPECT_EQ(l.dag_nodes, 1u);
  }
}

}  // namespace
}  // namespace kiln
