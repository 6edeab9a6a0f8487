// Voxels, part 1, checked independently of the voxelizer's binning, bricks and column walk:
// the surface voxelizer against a brute-force enumeration (corpus meshes up to 256^3, generated
// worst cases on grid planes, brick seams, the largest resolution), against points sampled on the
// triangles (a check that does not use the voxelizer's predicate at all), per-voxel normals
// against brute-force sums, thread-count independence and the grid fit; the voxel DAG against the
// plain octree (SVO) it compresses: expansion, per-level statistics recomputed from the codes,
// word layout, maximal merging, refusals and determinism.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/voxel_dag_builder.hpp"
#include "kiln/compiler/voxelizer.hpp"
#include "kiln/formats/voxel_dag.hpp"
#include "test_support.hpp"
#include "voxel_fixtures.hpp"

namespace kiln {
namespace {

using format::Double3;
using format::Float3;
using Tri = std::array<Float3, 3>;
using test::brute_force_hits;
using test::grid_triangle;
using test::Sweep;

Scene corpus(const std::string& mesh) {
  return import_scene({test::mesh_path(mesh)}, 2);
}

Scene triangles_scene(const std::vector<Tri>& triangles) {
  Scene scene;
  for (const Tri& t : triangles) {
    const auto base = std::uint32_t(scene.positions.size());
    scene.positions.insert(scene.positions.end(), t.begin(), t.end());
    scene.triangles.push_back({{base, base + 1, base + 2}});
    scene.triangle_mesh.push_back(0);
  }
  scene.input_triangle_count = scene.triangles.size();
  scene.bounds = bounds_of(scene.positions);
  scene.sources.push_back({"generated", 0, 0});
  scene.meshes.push_back({"generated", 0, 0, scene.triangles.size(), 0, scene.positions.size()});
  return scene;
}

std::string voxel_name(std::uint64_t code) {
  return "(" + std::to_string(format::compact_bits(code)) + ", " +
         std::to_string(format::compact_bits(code >> 1)) + ", " +
         std::to_string(format::compact_bits(code >> 2)) + ")";
}

std::vector<std::uint64_t> codes_of(const std::vector<std::pair<std::uint64_t, std::uint32_t>>& h) {
  std::vector<std::uint64_t> codes;
  for (const auto& [code, triangle] : h)
    if (codes.empty() || codes.back() != code) codes.push_back(code);
  return codes;
}

std::vector<std::uint64_t> brute_force(const Scene& scene, const VoxelGrid& grid, Sweep sweep) {
  return codes_of(brute_force_hits(scene, grid, sweep));
}

// Per voxel, the sum of the unit normals of the triangles touching it, in triangle order (the
// voxelizer's documented rule), octahedral-encoded.
std::vector<std::uint32_t> brute_force_normals(
    const Scene& scene, const std::vector<std::pair<std::uint64_t, std::uint32_t>>& hits) {
  std::vector<std::uint32_t> normals;
  for (std::size_t k = 0; k < hits.size();) {
    double sum[3] = {0, 0, 0};
    std::size_t end = k;
    for (; end < hits.size() && hits[end].first == hits[k].first; ++end) {
      const auto& tri = scene.triangles[hits[end].second];
      const Double3 a = to_d(scene.positions[tri.v[0]]), b = to_d(scene.positions[tri.v[1]]),
                    c = to_d(scene.positions[tri.v[2]]);
      const Double3 nrm = cross(b - a, c - a);
      const double length = std::sqrt(dot(nrm, nrm));
      for (int axis = 0; axis < 3; ++axis) sum[axis] += format::at(nrm, axis) / length;
    }
    normals.push_back(format::encode_octahedral(float(sum[0]), float(sum[1]), float(sum[2])));
    k = end;
  }
  return normals;
}

// Counts and the first few voxels only one side has.
std::string describe_difference(const std::vector<std::uint64_t>& actual,
                                const std::vector<std::uint64_t>& expected) {
  std::vector<std::uint64_t> missing, extra;
  std::set_difference(expected.begin(), expected.end(), actual.begin(), actual.end(),
                      std::back_inserter(missing));
  std::set_difference(actual.begin(), actual.end(), expected.begin(), expected.end(),
                      std::back_inserter(extra));
  std::ostringstream s;
  s << "voxelizer " << actual.size() << " voxels, brute force " << expected.size() << "; missing "
    << missing.size() << ":";
  for (std::size_t i = 0; i < std::min<std::size_t>(8, missing.size()); ++i)
    s << ' ' << voxel_name(missing[i]);
  s << "; extra " << extra.size() << ":";
  for (std::size_t i = 0; i < std::min<std::size_t>(8, extra.size()); ++i)
    s << ' ' << voxel_name(extra[i]);
  return s.str();
}

void expect_sorted_in_grid(const std::vector<std::uint64_t>& codes, std::uint32_t n,
                           const std::string& what) {
  ASSERT_FALSE(codes.empty()) << what;
  EXPECT_TRUE(std::adjacent_find(codes.begin(), codes.end(), std::greater_equal<>()) == codes.end())
      << what << ": codes not strictly ascending";
  const std::uint64_t cells = std::uint64_t(n) * n * n;
  EXPECT_LT(codes.back(), cells) << what;
  EXPECT_TRUE(std::all_of(codes.begin(), codes.end(), [&](std::uint64_t c) { return c < cells; }))
      << what;
}

// voxelize_surface at resolution n against the brute force; returns the voxelizer's output.
Voxels expect_matches_brute_force(const Scene& scene, std::uint32_t n, Sweep sweep,
                                  const std::string& what) {
  const Voxels voxels = voxelize_surface(scene, {n, false, 2});
  const std::string where = what + " at " + std::to_string(n) + "^3";
  expect_sorted_in_grid(voxels.codes, n, where);
  EXPECT_TRUE(voxels.normals.empty()) << where;
  const VoxelGrid fitted = fit_voxel_grid(scene.bounds, n);
  EXPECT_EQ(voxels.grid.resolution, n) << where;
  EXPECT_EQ(voxels.grid.voxel_size, fitted.voxel_size) << where;
  EXPECT_EQ(voxels.grid.origin, fitted.origin) << where;
  const auto expected = brute_force(scene, voxels.grid, sweep);
  EXPECT_TRUE(voxels.codes == expected)
      << where << ": " << describe_difference(voxels.codes, expected);
  return voxels;
}

// Points on every triangle (corners, edge midpoints, centroid and `random_points` uniform ones)
// must lie in a set voxel: a conservative voxelization holds the whole surface. Independent of
// triangle_touches_voxel. Points within 1e-6 voxels of a grid plane are skipped (which voxel
// holds them depends on rounding).
void expect_holds_surface_samples(const Scene& scene, const Voxels& voxels, int random_points,
                                  const std::string& what) {
  const std::uint32_t n = voxels.grid.resolution;
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> unit(0, 1);
  std::size_t tested = 0, missing = 0;
  std::string first;
  for (std::size_t i = 0; i < scene.triangles.size(); ++i) {
    const GridTriangle t = grid_triangle(scene, voxels.grid, i);
    std::vector<std::array<double, 3>> weights = {{1, 0, 0},
                                                  {0, 1, 0},
                                                  {0, 0, 1},
                                                  {0.5, 0.5, 0},
                                                  {0, 0.5, 0.5},
                                                  {0.5, 0, 0.5},
                                                  {1. / 3, 1. / 3, 1. / 3}};
    for (int k = 0; k < random_points; ++k) {
      const double r1 = std::sqrt(unit(rng)), r2 = unit(rng);
      weights.push_back({1 - r1, r1 * (1 - r2), r1 * r2});
    }
    for (const auto& w : weights) {
      const Double3 p = t.v[0] * w[0] + t.v[1] * w[1] + t.v[2] * w[2];
      std::uint32_t cell[3];
      bool usable = true;
      for (int a = 0; a < 3; ++a) {
        const double c = format::at(p, a);
        if (!(c > 1e-6 && c < n - 1e-6) || std::fabs(c - std::round(c)) < 1e-6) usable = false;
        cell[a] = usable ? std::uint32_t(std::floor(c)) : 0;
      }
      if (!usable) continue;
      ++tested;
      const std::uint64_t code = format::morton_code(cell[0], cell[1], cell[2]);
      if (!std::binary_search(voxels.codes.begin(), voxels.codes.end(), code)) {
        if (missing++ == 0)
          first = "triangle " + std::to_string(i) + ", point (" + std::to_string(p.x) + ", " +
                  std::to_string(p.y) + ", " + std::to_string(p.z) + ") in voxel " +
                  voxel_name(code);
      }
    }
  }
  EXPECT_GT(tested, 0u) << what;
  EXPECT_EQ(missing, 0u) << what << " at " << n << "^3: " << tested << " points, first missing "
                         << first;
}

// ---------------------------------------------------------------------------------------------
// Voxelizer

// Named apart from voxelizer_test.cpp's MatchesBruteForceOnCorpusMeshes (every-voxel brute force
// up to 32^3): this one goes to 256^3 with the box-plus-two sweep, adds the teapot and the bunny,
// and samples the surface.
TEST(Voxelizer, MatchesBruteForceOnCorpusMeshesUpTo256) {
  KILN_REQUIRE_CORPUS();
  const std::vector<std::pair<const char*, std::vector<std::uint32_t>>> cases = {
      {"classic/teapot.obj", {16, 32, 64, 128}},
      {"classic/spot.obj", {16, 32, 64, 128}},
      {"stanford/stanford-bunny.obj.zst", {16, 32, 64, 128, 256}},  // 256: 8 bricks, seams
      {"assimp/OBJ/spider.obj", {16, 32, 64, 128}}};
  for (const auto& [mesh, resolutions] : cases) {
    const Scene scene = corpus(mesh);
    ASSERT_FALSE(scene.triangles.empty()) << mesh;
    for (const std::uint32_t n : resolutions) {
      const Voxels voxels = expect_matches_brute_force(scene, n, Sweep::kBoxPlus2, mesh);
      expect_holds_surface_samples(scene, voxels, n <= 64 ? 4 : 1, mesh);
    }
  }
  // The two sweeps agree (the box-plus-two shortcut loses nothing).
  for (const char* mesh : {"classic/teapot.obj", "assimp/OBJ/spider.obj"}) {
    const Scene scene = corpus(mesh);
    const VoxelGrid grid = fit_voxel_grid(scene.bounds, 16);
    EXPECT_EQ(brute_force(scene, grid, Sweep::kWholeGrid),
              brute_force(scene, grid, Sweep::kBoxPlus2))
        << mesh;
  }
}

// Two tiny triangles at the corners (0,0,0) and (8,8,8) pin the scene's bounds, so the grid is
// [0, 8]^3 and voxel faces lie on multiples of 8 / n: integers are grid planes at every
// resolution, multiples of 1/8 at 64^3.
std::vector<Tri> anchored(std::vector<Tri> triangles) {
  triangles.push_back({{{0, 0, 0}, {0.01f, 0, 0}, {0, 0.01f, 0.005f}}});
  triangles.push_back({{{8, 8, 8}, {7.99f, 8, 8}, {8, 7.99f, 7.995f}}});
  return triangles;
}

std::vector<std::pair<std::string, std::vector<Tri>>> worst_cases() {
  std::vector<std::pair<std::string, std::vector<Tri>>> cases = {
      {"in plane z = 2, hypotenuse through voxel corners", {{{{1, 1, 2}, {5, 1, 2}, {1, 5, 2}}}}},
      {"in plane x = 3, spanning the grid", {{{{3, 0, 0}, {3, 8, 0}, {3, 0, 8}}}}},
      {"in plane y = 0 (grid min face)", {{{{0, 0, 1}, {7, 0, 2}, {3, 0, 7}}}}},
      {"in plane y = 8 (grid max face)", {{{{0, 8, 0}, {8, 8, 0}, {8, 8, 8}}}}},
      {"on the grid max face z = 8 along its max edges", {{{{8, 8, 8}, {0, 8, 8}, {8, 0, 8}}}}},
      {"in plane x = 8 (grid max face), small",
       {{{{8, 3.5f, 3.5f}, {8, 4.5f, 3.5f}, {8, 3.5f, 4.25f}}}}},
      {"plane x - z = -2 through voxel edges", {{{{1, 2, 3}, {5, 2, 7}, {1, 6, 3}}}}},
      {"plane x + y + z = 12 through voxel corners", {{{{4, 4, 4}, {8, 4, 0}, {0, 8, 4}}}}},
      {"plane x + y = 8 through voxel edges, vertical", {{{{0, 8, 0}, {8, 0, 0}, {4, 4, 8}}}}},
      {"huge slanted through grid corners", {{{{0, 0, 0}, {8, 8, 0}, {0, 8, 8}}}}},
      {"huge slanted generic", {{{{0.3f, 0, 7.7f}, {8, 0.6f, 0}, {0.1f, 8, 0.9f}}}}},
      {"sliver along the main diagonal",
       {{{{0.1f, 0.1f, 0.1f}, {7.9f, 7.9f, 7.9f}, {7.9f, 7.9f, 7.90001f}}}}},
      {"sliver on a voxel edge line (y = 2, z = 3)", {{{{0, 2, 3}, {8, 2, 3}, {8, 2, 3.001f}}}}},
      {"sliver in plane z = 4 along a face diagonal", {{{{0, 0, 4}, {8, 8, 4}, {8, 7.999f, 4}}}}},
      {"sliver 1e-6 wide, slanted", {{{{0, 1, 1}, {8, 7, 5}, {8, 7.000001f, 5}}}}},
      {"tiny, inside one voxel", {{{{3.2f, 3.2f, 3.2f}, {3.3f, 3.2f, 3.2f}, {3.2f, 3.3f, 3.25f}}}}},
      {"tiny, at a voxel corner (4, 4, 4)", {{{{4, 4, 4}, {4.001f, 4, 4}, {4, 4.001f, 4}}}}},
      {"tiny, on a voxel face z = 6", {{{{2.5f, 2.5f, 6}, {2.6f, 2.5f, 6}, {2.5f, 2.6f, 6}}}}},
      {"tiny, touching the grid max corner", {{{{8, 8, 8}, {7.999f, 8, 8}, {8, 7.999f, 7.9995f}}}}},
      {"tiny, on a voxel edge", {{{{2, 3, 1.5f}, {2, 3, 1.6f}, {2.05f, 3, 1.55f}}}}},
      {"nearly edge-on", {{{{4, 4, 4}, {6, 4, 4}, {4, 4.000001f, 6}}}}},
      {"fan around a lattice point",
       {{{{4, 4, 4}, {6, 4, 4}, {4, 6, 4}}},
        {{{4, 4, 4}, {4, 6, 4}, {2, 4, 4}}},
        {{{4, 4, 4}, {2, 4, 4}, {4, 2, 4}}},
        {{{4, 4, 4}, {4, 2, 4}, {6, 4, 4}}},
        {{{4, 4, 4}, {4, 4, 6}, {6, 6, 6}}}}},
  };
  // Random triangles with corners snapped to multiples of 1/2 (on grid planes at 16^3 and up)
  // and to multiples of 1/8 (on grid planes at 64^3), and unsnapped ones.
  std::mt19937 rng(31);
  for (const float step : {0.5f, 0.125f, 0.0f}) {
    std::uniform_real_distribution<float> coordinate(0, 8);
    auto pick = [&] {
      const float c = coordinate(rng);
      return step > 0 ? std::round(c / step) * step : c;
    };
    std::vector<Tri> random;
    while (random.size() < 30) {
      const Tri t = {
          {{pick(), pick(), pick()}, {pick(), pick(), pick()}, {pick(), pick(), pick()}}};
      const Double3 nrm = cross(to_d(t[1]) - to_d(t[0]), to_d(t[2]) - to_d(t[0]));
      if (dot(nrm, nrm) > 1e-6) random.push_back(t);  // the importer drops degenerate ones
    }
    cases.push_back({"random, snapped to " + std::to_string(step), random});
  }
  return cases;
}

TEST(Voxelizer, GeneratedWorstCases) {
  // Every voxel of the grid against every triangle (kWholeGrid), 8^3 .. 64^3.
  for (const auto& [name, triangles] : worst_cases()) {
    const Scene scene = triangles_scene(anchored(triangles));
    ASSERT_EQ(scene.bounds.min.x, 0.0f);
    ASSERT_EQ(scene.bounds.max.z, 8.0f);
    for (const std::uint32_t n : {8u, 16u, 32u, 64u}) {
      const Voxels voxels = expect_matches_brute_force(scene, n, Sweep::kWholeGrid, name);
      expect_holds_surface_samples(scene, voxels, 50, name);
    }
  }
  // Brick seams: bricks are 128 voxels, so at 256^3 the grid planes x, y, z = 4 are seams and at
  // 512^3 also 2 and 6 (box-plus-two sweep: whole grids are too slow here).
  const std::vector<std::pair<std::string, std::vector<Tri>>> seams = {
      {"in the seam plane x = 4", {{{{4, 3, 3}, {4, 5, 3}, {4, 3, 5}}}}},
      {"in the seam plane z = 4, large", {{{{0, 0, 4}, {8, 0, 4}, {0, 8, 4}}}}},
      {"slanted, thin in z, across every seam", {{{{0, 0, 3.9f}, {8, 0, 4.1f}, {0, 8, 4}}}}},
      {"across the seam corner (4, 4, 4)",
       {{{{3.5f, 3.6f, 3.7f}, {4.5f, 4.2f, 3.9f}, {3.8f, 4.4f, 4.3f}}}}},
      {"tiny, at the seam corner", {{{{4, 4, 4}, {4.01f, 4, 4}, {4, 4.01f, 4.01f}}}}},
      {"sliver along the seam line y = 2, z = 6", {{{{0, 2, 6}, {8, 2, 6}, {8, 2.001f, 6}}}}},
  };
  for (const auto& [name, triangles] : seams) {
    const Scene scene = triangles_scene(anchored(triangles));
    for (const std::uint32_t n : {256u, 512u}) {
      const Voxels voxels = expect_matches_brute_force(scene, n, Sweep::kBoxPlus2, name);
      expect_holds_surface_samples(scene, voxels, 200, name);
    }
  }
  // A grid not starting at the bounds' minimum on every axis: bounds [0, 8] x [0, 2] x [-1, 1],
  // so the cube is centred in y and z (origin -3, -4) and the bounds' y and z faces are grid
  // planes inside the grid.
  {
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> x(0, 8), y(0, 2), z(-1, 1);
    std::vector<Tri> slab = {{{{0, 0, -1}, {8, 2, 1}, {8, 0, 1}}},
                             {{{0, 2, 0}, {8, 2, 0}, {4, 2, 1}}}};  // on the face y = 2
    for (int i = 0; i < 20; ++i)
      slab.push_back(
          {{{x(rng), y(rng), z(rng)}, {x(rng), y(rng), z(rng)}, {x(rng), y(rng), z(rng)}}});
    const Scene scene = triangles_scene(slab);
    for (const std::uint32_t n : {8u, 16u, 32u, 64u})
      expect_matches_brute_force(scene, n, Sweep::kWholeGrid, "off-centre slab");
  }
  // A flat scene (zero extent in z): the grid is centred on the plane, which is a grid plane.
  {
    const Scene flat =
        triangles_scene({{{{0, 0, 5}, {3, 0, 5}, {3, 3, 5}}}, {{{0, 0, 5}, {3, 3, 5}, {0, 3, 5}}}});
    for (const std::uint32_t n : {8u, 16u, 32u, 64u})
      expect_matches_brute_force(flat, n, Sweep::kWholeGrid, "flat square");
  }
  // The largest whole-grid resolution: 16384^3 (128 bricks per axis, 42-bit codes) on a long
  // sliver.
  {
    const Scene sliver = triangles_scene({{{{0, 0, 0}, {1, 0, 0}, {1, 1e-4f, 0}}}});
    const Voxels v = expect_matches_brute_force(sliver, format::kVoxelInCoreMaxResolution,
                                                Sweep::kBoxPlus2, "sliver");
    EXPECT_GE(v.codes.size(), std::size_t(format::kVoxelInCoreMaxResolution));
  }
}

// Exact per-voxel normals against the brute-force sums, thread-count independence of codes and
// normals, unit normals, and flat meshes whose every voxel normal is the plane's.
TEST(Voxelizer, ByteIdenticalAcrossThreadCountsAndNormals) {
  // Coplanar grids of triangles: facing +z, and tilted to (0, -0.6, 0.8).
  auto plane_grid = [](auto point) {
    std::vector<Tri> triangles;
    for (int i = 0; i < 12; ++i)
      for (int j = 0; j < 12; ++j) {
        const Float3 a = point(i, j), b = point(i + 1, j), c = point(i + 1, j + 1),
                     d = point(i, j + 1);
        triangles.push_back({{a, b, c}});
        triangles.push_back({{a, c, d}});
      }
    return triangles_scene(triangles);
  };
  const Scene flat = plane_grid([](int i, int j) { return Float3{0.25f * i, 0.25f * j, 1.5f}; });
  const Scene tilted = plane_grid([](int i, int j) {
    return Float3{0.25f * i, 0.2f * j - 1.0f, 0.15f * j + 2.0f};
  });
  for (const auto& [scene, expected] :
       {std::pair<const Scene*, Double3>{&flat, {0, 0, 1}}, {&tilted, {0, -0.6, 0.8}}}) {
    for (const std::uint32_t n : {8u, 32u, 128u}) {
      const Voxels v = voxelize_surface(*scene, {n, true, 2});
      ASSERT_EQ(v.normals.size(), v.codes.size());
      ASSERT_FALSE(v.codes.empty());
      std::size_t off = 0;
      for (const std::uint32_t bits : v.normals) {
        float d[3];
        format::decode_octahedral(bits, d);
        off += std::fabs(d[0] - expected.x) > 1e-3 || std::fabs(d[1] - expected.y) > 1e-3 ||
               std::fabs(d[2] - expected.z) > 1e-3;
      }
      EXPECT_EQ(off, 0u) << "plane normal (" << expected.x << ", " << expected.y << ", "
                         << expected.z << ") at " << n << "^3";
      // The brute-force sums, bit for bit.
      const auto hits =
          brute_force_hits(*scene, v.grid, n <= 32 ? Sweep::kWholeGrid : Sweep::kBoxPlus2);
      EXPECT_EQ(v.codes, codes_of(hits));
      EXPECT_EQ(v.normals, brute_force_normals(*scene, hits));
    }
  }
  KILN_REQUIRE_CORPUS();
  {
    const Scene teapot = corpus("classic/teapot.obj");
    const Voxels v = voxelize_surface(teapot, {64, true, 2});
    const auto hits = brute_force_hits(teapot, v.grid, Sweep::kBoxPlus2);
    EXPECT_EQ(v.codes, codes_of(hits));
    EXPECT_EQ(v.normals, brute_force_normals(teapot, hits)) << "teapot 64^3 normals";
  }
  const Scene bunny = corpus("stanford/stanford-bunny.obj.zst");
  const Voxels one = voxelize_surface(bunny, {256, true, 1});
  expect_sorted_in_grid(one.codes, 256, "bunny 256^3");
  ASSERT_EQ(one.normals.size(), one.codes.size());
  for (const unsigned threads : {2u, 8u, 0u}) {
    const Voxels other = voxelize_surface(bunny, {256, true, threads});
    EXPECT_TRUE(other.codes == one.codes) << threads << " threads";
    EXPECT_TRUE(other.normals == one.normals) << threads << " threads";
    EXPECT_EQ(other.grid.origin, one.grid.origin);
    EXPECT_EQ(other.grid.voxel_size, one.grid.voxel_size);
  }
  // Without normals: the same codes.
  EXPECT_TRUE(voxelize_surface(bunny, {256, false, 8}).codes == one.codes);
  std::size_t not_unit = 0;
  for (const std::uint32_t bits : one.normals) {
    float d[3];
    format::decode_octahedral(bits, d);
    not_unit += !(std::fabs(d[0] * d[0] + d[1] * d[1] + d[2] * d[2] - 1.0f) < 1e-4f);
  }
  EXPECT_EQ(not_unit, 0u);
}

// Named apart from voxelizer_test.cpp's RefusesBadResolutions.
TEST(Voxelizer, RefusesResolutionsOutsidePowersOfTwo8To16384) {
  const Scene scene = triangles_scene({{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}}});
  for (const std::uint32_t n :
       {0u, 1u, 2u, 3u, 4u, 6u, 12u, 100u, 1000u, 16383u, 16385u, format::kVoxelMaxResolution * 2,
        1u << 31, std::numeric_limits<std::uint32_t>::max()})
    EXPECT_THROW(voxelize_surface(scene, {n, false, 1}), std::invalid_argument) << n;
  EXPECT_LT(4u, format::kVoxelMinResolution);
  for (const std::uint32_t n : {format::kVoxelMinResolution, 16u, 1024u})
    EXPECT_NO_THROW(voxelize_surface(scene, {n, false, 1})) << n;
}

// Random scene bounds of six kinds (0 ordinary, 1 far from the origin and small, 2 flat or a
// line, 3 a point, 4 min and max of very different magnitudes, 5 negative with uneven extents).
format::Box3f random_bounds(std::mt19937& rng, int kind) {
  std::uniform_real_distribution<float> unit(0, 1);
  float lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    float l = 0, h = 0;
    switch (kind) {
      case 0:
        l = -10 + 20 * unit(rng), h = l + 10 * unit(rng);
        break;
      case 1:
        l = 1e6f * (unit(rng) - 0.5f) * 20, h = l + 1e-2f * unit(rng);
        break;
      case 2:
        l = 100 * unit(rng), h = (unit(rng) < 0.5f) ? l : l + unit(rng);
        break;
      case 3:
        l = h = 1000 * (unit(rng) - 0.5f);
        break;
      case 4:  // |min| and |max| each 2^-20 .. 2^20
        l = -std::ldexp(unit(rng), int(unit(rng) * 40) - 20),
        h = std::ldexp(unit(rng), int(unit(rng) * 40) - 20);
        break;
      default:
        h = -unit(rng) * 50, l = h - std::ldexp(unit(rng), a * 4);
        break;
    }
    lo[a] = l, hi[a] = h;
  }
  format::Box3f b;
  b.min = {lo[0], lo[1], lo[2]}, b.max = {hi[0], hi[1], hi[2]};
  return b;
}

std::string bounds_name(const format::Box3f& b) {
  std::ostringstream s;
  s.precision(17);
  s << "bounds [" << b.min.x << ", " << b.min.y << ", " << b.min.z << "] .. [" << b.max.x << ", "
    << b.max.y << ", " << b.max.z << "]";
  return s.str();
}

// The fitted grid is a cube of side = the largest extent, centred, holding the bounds on every
// axis, in world space and in grid units.
TEST(Voxelizer, FittedGridHoldsTheBounds) {
  // Plain cases first: a mesh whose min on its largest axis is float noise around 0.
  for (const auto& [lo, hi] :
       std::vector<std::pair<Float3, Float3>>{{{0.05f, 1e-9f, 0.05f}, {0.95f, 1, 0.95f}},
                                              {{-1e-7f, 0, 0}, {100, 1, 1}},
                                              {{-1e-9f, 0, 0}, {1000, 1, 1}},
                                              {{0, 0, 0}, {1, 1, 1}},
                                              {{-1, -2, -3}, {1, 2, 3}}}) {
    const format::Box3f b{lo, hi};
    for (const std::uint32_t n : {64u}) {  // the origin does not depend on n
      const VoxelGrid g = fit_voxel_grid(b, n);
      const double side = n * g.voxel_size;
      const float l[3] = {lo.x, lo.y, lo.z}, h[3] = {hi.x, hi.y, hi.z};
      for (int a = 0; a < 3; ++a) {
        std::ostringstream s;
        s.precision(17);
        s << bounds_name(b) << ", " << n << "^3, axis " << a << ": origin " << g.origin[a]
          << ", origin + side " << g.origin[a] + side;
        EXPECT_LE(g.origin[a], l[a]) << s.str();
        EXPECT_GE(g.origin[a] + side, h[a]) << s.str();
      }
    }
  }
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> kind(0, 5);
  // Per check: how many (bounds, resolution) pairs fail it, per kind of bounds, and the first.
  const char* const checks[] = {"cube side = largest extent (rounded up)",
                                "origin <= min",
                                "origin + side >= max",
                                "min in grid units >= 0",
                                "max in grid units <= n",
                                "centred"};
  std::size_t failures[6][6] = {};
  std::string first[6];
  for (int i = 0; i < 3000; ++i) {
    const int k = kind(rng);
    const format::Box3f b = random_bounds(rng, k);
    const float lo[3] = {b.min.x, b.min.y, b.min.z}, hi[3] = {b.max.x, b.max.y, b.max.z};
    double extent = 0;
    for (int a = 0; a < 3; ++a) extent = std::max(extent, double(hi[a]) - double(lo[a]));
    for (const std::uint32_t n : {8u, 64u, 1024u, 16384u}) {
      const VoxelGrid g = fit_voxel_grid(b, n);
      const double side = n * g.voxel_size;
      const GridTriangle t = to_grid(g, b.min, b.max, b.max);
      bool ok[6] = {g.resolution == n && g.voxel_size > 0 &&
                        (extent > 0 ? side >= extent && side <= extent * (1 + 1e-12) : side > 0),
                    true,
                    true,
                    true,
                    true,
                    true};
      for (int a = 0; a < 3; ++a) {
        ok[1] = ok[1] && g.origin[a] <= lo[a];
        ok[2] = ok[2] && g.origin[a] + side >= hi[a];
        ok[3] = ok[3] && format::at(t.v[0], a) >= 0;
        ok[4] = ok[4] && format::at(t.v[1], a) <= n;
        ok[5] = ok[5] && std::fabs(g.origin[a] + 0.5 * side - 0.5 * (double(lo[a]) + hi[a])) <=
                             1e-12 * (std::fabs(lo[a]) + std::fabs(hi[a]) + side);
      }
      for (int c = 0; c < 6; ++c) {
        if (ok[c] || !first[c].empty()) {
          failures[c][k] += !ok[c];
          continue;
        }
        failures[c][k] += 1;
        std::ostringstream s;
        s.precision(17);
        s << "kind " << k << ", n " << n << ", " << bounds_name(b) << ", origin [" << g.origin[0]
          << ", " << g.origin[1] << ", " << g.origin[2] << "], voxel " << g.voxel_size
          << ", corners in grid units [" << t.v[0].x << ", " << t.v[0].y << ", " << t.v[0].z
          << "] .. [" << t.v[1].x << ", " << t.v[1].y << ", " << t.v[1].z << "]";
        first[c] = s.str();
      }
    }
  }
  for (int c = 0; c < 6; ++c) {
    std::size_t total = 0;
    std::string per_kind;
    for (int k = 0; k < 6; ++k) {
      total += failures[c][k];
      per_kind += (k ? ", " : "") + std::to_string(failures[c][k]);
    }
    EXPECT_EQ(total, 0u) << checks[c] << ": failures per kind of bounds [" << per_kind
                         << "] of 3000 x 4 resolutions; first: " << first[c];
  }
}

// A triangle lying in a face of the scene's bounds sets the boundary voxels under it (the
// header's promise: "a triangle on the bounds' faces sets the boundary voxels"). Six triangles,
// one in each face of random bounds; the voxel holding each one's centroid (clamped to the grid)
// must be set.
TEST(Voxelizer, KeepsTrianglesOnTheBoundsFaces) {
  // A plain case: a unit-sized mesh whose floor sits at y = 1e-9 (exporter noise for 0) and whose
  // largest extent is y. The floor triangle lies in the bounds' min face.
  {
    const Scene scene =
        triangles_scene({{{{0.05f, 1e-9f, 0.05f}, {0.95f, 1e-9f, 0.05f}, {0.05f, 1e-9f, 0.95f}}},
                         {{{0.05f, 1, 0.05f}, {0.5f, 1, 0.05f}, {0.05f, 1, 0.5f}}}});
    for (const std::uint32_t n : {8u, 64u, 512u}) {
      const Voxels voxels = voxelize_surface(scene, {n, false, 1});
      const GridTriangle floor = grid_triangle(scene, voxels.grid, 0);
      std::size_t bottom_layer = 0;
      for (const std::uint64_t c : voxels.codes) bottom_layer += format::compact_bits(c >> 1) == 0;
      std::ostringstream s;
      s.precision(17);
      s << "floor at y = 1e-9, " << n << "^3: floor corners at grid y = " << floor.v[0].y
        << ", grid origin y = " << voxels.grid.origin[1] << ", voxel " << voxels.grid.voxel_size;
      // The floor covers about 0.9^2 / 2 of the bottom layer: at least n^2 / 4 voxels.
      EXPECT_GE(bottom_layer, std::size_t(n) * n / 4) << s.str();
    }
  }
  std::mt19937 rng(3);
  std::size_t scenes = 0, failures[6] = {};
  std::string first;
  for (int i = 0; i < 3000; ++i) {
    const int k = i % 6;
    const format::Box3f b = random_bounds(rng, k);
    const float lo[3] = {b.min.x, b.min.y, b.min.z}, hi[3] = {b.max.x, b.max.y, b.max.z};
    std::vector<Tri> faces;
    for (int a = 0; a < 3; ++a)
      for (const float plane : {lo[a], hi[a]}) {
        const int u = (a + 1) % 3, v = (a + 2) % 3;
        float p[3][3];
        for (int c = 0; c < 3; ++c) p[c][a] = plane, p[c][u] = lo[u], p[c][v] = lo[v];
        p[1][u] = hi[u], p[2][v] = hi[v];
        faces.push_back({{{p[0][0], p[0][1], p[0][2]},
                          {p[1][0], p[1][1], p[1][2]},
                          {p[2][0], p[2][1], p[2][2]}}});
      }
    std::vector<Tri> kept;
    for (const Tri& t : faces) {
      const Double3 nrm = cross(to_d(t[1]) - to_d(t[0]), to_d(t[2]) - to_d(t[0]));
      if (dot(nrm, nrm) > 0) kept.push_back(t);  // flat bounds: degenerate faces dropped
    }
    if (kept.empty()) continue;
    Scene scene = triangles_scene(kept);
    scene.bounds = b;  // the same box (bounds_of gives it back), set to be sure
    ++scenes;
    for (const std::uint32_t n : {8u, 64u}) {
      const Voxels voxels = voxelize_surface(scene, {n, false, 1});
      for (std::size_t f = 0; f < kept.size(); ++f) {
        const GridTriangle t = grid_triangle(scene, voxels.grid, f);
        const Double3 centroid = (t.v[0] + t.v[1] + t.v[2]) * (1.0 / 3);
        std::uint32_t cell[3];
        for (int a = 0; a < 3; ++a)
          cell[a] = std::uint32_t(std::clamp(std::floor(format::at(centroid, a)), 0.0, n - 1.0));
        const std::uint64_t code = format::morton_code(cell[0], cell[1], cell[2]);
        if (std::binary_search(voxels.codes.begin(), voxels.codes.end(), code)) continue;
        if (failures[k]++ == 0 && first.empty()) {
          std::ostringstream s;
          s.precision(17);
          s << "kind " << k << ", n " << n << ", " << bounds_name(b) << ": face triangle " << f
            << " (" << kept[f][0].x << ", " << kept[f][0].y << ", " << kept[f][0].z << ") ("
            << kept[f][1].x << ", " << kept[f][1].y << ", " << kept[f][1].z << ") (" << kept[f][2].x
            << ", " << kept[f][2].y << ", " << kept[f][2].z << "), grid units (" << t.v[0].x << ", "
            << t.v[0].y << ", " << t.v[0].z << ") (" << t.v[1].x << ", " << t.v[1].y << ", "
            << t.v[1].z << ") (" << t.v[2].x << ", " << t.v[2].y << ", " << t.v[2].z << "): voxel "
            << voxel_name(code) << " not set; the scene has " << voxels.codes.size() << " voxels";
          first = s.str();
        }
      }
    }
  }
  EXPECT_GT(scenes, 1500u);  // kind 3 (points) and some flat kind-2 bounds have no face
  std::string per_kind;
  std::size_t total = 0;
  for (int k = 0; k < 6; ++k)
    per_kind += (k ? ", " : "") + std::to_string(failures[k]), total += failures[k];
  EXPECT_EQ(total, 0u) << "face triangles missing, per kind of bounds [" << per_kind
                       << "]; first: " << first;
}

// ---------------------------------------------------------------------------------------------
// Voxel DAG

// Everything the DAG promises about `codes`, recomputed from the codes and from the words.
void expect_dag_of(const std::vector<std::uint64_t>& codes, std::uint32_t n,
                   const std::string& what) {
  SCOPED_TRACE(what + " at " + std::to_string(n) + "^3");
  const FlatVoxelDag dag = build_voxel_dag(codes, n);
  const std::uint32_t levels = std::uint32_t(std::countr_zero(n));
  ASSERT_EQ(dag.levels, levels);
  ASSERT_EQ(dag.level_stats.size(), levels - 1);
  EXPECT_TRUE(expand_voxel_dag(dag.words, dag.levels) == codes);
  EXPECT_EQ(dag.voxel_count, codes.size());

  // The plain octree: level l (0 = root .. levels - 2 = 4x4x4 leaves) has one node per distinct
  // code >> 3 (levels - l); each interior node is a header plus a word per child, a leaf 8 bytes.
  const std::uint32_t leaf_level = levels - 2;
  std::vector<std::uint64_t> svo(levels - 1);
  for (std::uint32_t l = 0; l <= leaf_level; ++l) {
    std::uint64_t count = 0, previous = ~std::uint64_t{0};
    for (const std::uint64_t c : codes) {
      const std::uint64_t key = c >> 3 * (levels - l);
      count += key != previous, previous = key;
    }
    svo[l] = count;
    EXPECT_EQ(dag.level_stats[l].svo_nodes, count) << "level " << l;
  }
  EXPECT_EQ(dag.level_stats[0].svo_nodes, 1u);
  std::uint64_t svo_bytes = 8 * svo[leaf_level];
  for (std::uint32_t l = 0; l < leaf_level; ++l) svo_bytes += 4 * (svo[l] + svo[l + 1]);
  EXPECT_EQ(dag.svo_bytes, svo_bytes);

  std::uint64_t bytes = 0;
  for (std::uint32_t l = 0; l <= leaf_level; ++l) {
    const auto& s = dag.level_stats[l];
    EXPECT_GE(s.dag_nodes, 1u) << "level " << l;
    EXPECT_LE(s.dag_nodes, s.svo_nodes) << "level " << l;
    EXPECT_EQ(s.first_word, bytes / 4) << "level " << l;
    bytes += s.bytes;
  }
  EXPECT_EQ(dag.level_stats[leaf_level].bytes, 8 * dag.level_stats[leaf_level].dag_nodes);
  EXPECT_EQ(dag.leaf_first_word, dag.level_stats[leaf_level].first_word);
  EXPECT_EQ(bytes, dag.dag_bytes);
  EXPECT_EQ(dag.dag_bytes, 4 * dag.words.size());
  EXPECT_GE(dag.svo_bytes, dag.dag_bytes);

  // The words: each level parses into exactly dag_nodes nodes whose pointers land on node starts
  // of the next level (even offsets into the leaf masks), with no two nodes of a level equal
  // (maximal merging, given canonical children) and no empty node.
  std::set<std::uint64_t> starts_below;
  for (std::uint64_t w = dag.leaf_first_word; w < dag.words.size(); w += 2) starts_below.insert(w);
  std::set<std::uint64_t> masks;
  for (std::uint64_t w = dag.leaf_first_word; w + 1 < dag.words.size(); w += 2)
    masks.insert(dag.words[w] | std::uint64_t(dag.words[w + 1]) << 32);
  EXPECT_EQ(masks.size(), dag.level_stats[leaf_level].dag_nodes) << "duplicate leaf masks";
  EXPECT_EQ(masks.count(0), 0u) << "empty leaf mask";
  for (std::uint32_t l = leaf_level; l-- > 0;) {
    const std::uint64_t begin = dag.level_stats[l].first_word;
    const std::uint64_t end = begin + dag.level_stats[l].bytes / 4;
    std::set<std::uint64_t> starts;
    std::set<std::vector<std::uint32_t>> nodes;
    std::size_t bad = 0;
    for (std::uint64_t w = begin; w < end;) {
      starts.insert(w);
      const std::uint32_t header = dag.words[w];
      bad += header == 0 || header > 0xFF;
      const int children = std::popcount(header & 0xFFu);
      ASSERT_LE(w + 1 + children, end) << "level " << l << " node at word " << w;
      std::vector<std::uint32_t> node(dag.words.begin() + std::ptrdiff_t(w),
                                      dag.words.begin() + std::ptrdiff_t(w + 1 + children));
      for (int c = 0; c < children; ++c) bad += starts_below.count(node[1 + c]) == 0;
      nodes.insert(node);
      w += 1 + children;
    }
    EXPECT_EQ(bad, 0u) << "level " << l << ": bad headers or pointers";
    EXPECT_EQ(starts.size(), dag.level_stats[l].dag_nodes) << "level " << l;
    EXPECT_EQ(nodes.size(), starts.size()) << "level " << l << ": identical nodes not merged";
    starts_below = std::move(starts);
  }
  EXPECT_EQ(starts_below, std::set<std::uint64_t>{0}) << "the root is not word 0 alone";

  // leaves_of: the 4x4x4 blocks, brute force.
  const VoxelLeaves leaves = leaves_of(codes);
  std::map<std::uint64_t, std::uint64_t> blocks;
  for (const std::uint64_t c : codes) blocks[c >> 6] |= std::uint64_t{1} << (c & 63);
  ASSERT_EQ(leaves.keys.size(), blocks.size());
  ASSERT_EQ(leaves.masks.size(), blocks.size());
  EXPECT_EQ(leaves.voxel_count, codes.size());
  std::size_t i = 0;
  for (const auto& [key, mask] : blocks) {
    EXPECT_EQ(leaves.keys[i], key);
    EXPECT_EQ(leaves.masks[i], mask);
    ++i;
  }
}

std::vector<std::uint64_t> sorted_unique(std::vector<std::uint64_t> codes) {
  std::sort(codes.begin(), codes.end());
  codes.erase(std::unique(codes.begin(), codes.end()), codes.end());
  return codes;
}

std::vector<std::uint64_t> grid_where(std::uint32_t n, auto keep) {
  std::vector<std::uint64_t> codes;
  for (std::uint32_t z = 0; z < n; ++z)
    for (std::uint32_t y = 0; y < n; ++y)
      for (std::uint32_t x = 0; x < n; ++x)
        if (keep(x, y, z)) codes.push_back(format::morton_code(x, y, z));
  return sorted_unique(codes);
}

TEST(VoxelDag, ExpandsToTheSvoVoxelSet) {
  // Single voxels, at the corners and inside, up to the largest grid.
  for (const std::uint32_t n : {8u, 16u, 1024u, format::kVoxelMaxResolution})
    for (const auto& v : {std::array<std::uint32_t, 3>{0, 0, 0},
                          {n - 1, n - 1, n - 1},
                          {n / 2 - 1, n / 2, 1},
                          {n - 1, 0, n / 3}})
      expect_dag_of({format::morton_code(v[0], v[1], v[2])}, n,
                    "single voxel " + voxel_name(format::morton_code(v[0], v[1], v[2])));
  // Full grids and the checkerboard merge to one node per level.
  const auto full8 = grid_where(8, [](auto...) { return true; });
  const auto full16 = grid_where(16, [](auto...) { return true; });
  const auto checker16 =
      grid_where(16, [](auto x, auto y, auto z) { return (x + y + z) % 2 == 0; });
  ASSERT_EQ(full8.size(), 512u);
  ASSERT_EQ(checker16.size(), 2048u);
  for (const auto& [codes, n, name] : {std::tuple{&full8, 8u, "full 8^3"},
                                       {&full16, 16u, "full 16^3"},
                                       {&checker16, 16u, "checkerboard 16^3"}}) {
    expect_dag_of(*codes, n, name);
    const FlatVoxelDag dag = build_voxel_dag(*codes, n);
    for (std::uint32_t l = 0; l < dag.level_stats.size(); ++l)
      EXPECT_EQ(dag.level_stats[l].dag_nodes, 1u) << name << " level " << l;
  }
  // Half-space and sphere shells: structured sets with repeated subtrees.
  expect_dag_of(grid_where(64, [](auto x, auto y, auto z) { return x + 2 * y < 3 * z; }), 64,
                "half-space 64^3");
  expect_dag_of(grid_where(64,
                           [](auto x, auto y, auto z) {
                             const double r = std::hypot(x - 31.5, y - 31.5, z - 31.5);
                             return r > 20 && r < 22;
                           }),
                64, "sphere shell 64^3");
  // Random sparse sets, uniform and clustered (random walks), up to the largest grid.
  std::mt19937_64 rng(21);
  for (const std::uint32_t n : {8u, 32u, 256u, 4096u, format::kVoxelMaxResolution}) {
    const std::uint64_t cells = std::uint64_t(n) * n * n;
    std::vector<std::uint64_t> uniform;
    for (int i = 0; i < 2000; ++i) uniform.push_back(rng() % cells);
    expect_dag_of(sorted_unique(uniform), n, "uniform random");
    std::vector<std::uint64_t> walk;
    std::int64_t p[3] = {std::int64_t(n / 2), std::int64_t(n / 3), std::int64_t(n / 5)};
    for (int i = 0; i < 5000; ++i) {
      walk.push_back(
          format::morton_code(std::uint32_t(p[0]), std::uint32_t(p[1]), std::uint32_t(p[2])));
      const int axis = int(rng() % 3);
      p[axis] = std::clamp<std::int64_t>(p[axis] + (rng() % 2 ? 1 : -1), 0, n - 1);
    }
    expect_dag_of(sorted_unique(walk), n, "random walk");
  }
  {
    std::vector<std::uint64_t> dense;
    for (std::uint64_t c = 0; c < 32 * 32 * 32; ++c)
      if (rng() % 2) dense.push_back(c);
    expect_dag_of(dense, 32, "half full random 32^3");
  }
  // Surfaces of corpus meshes.
  KILN_REQUIRE_CORPUS();
  for (const auto& [mesh, n] :
       std::vector<std::pair<const char*, std::uint32_t>>{{"stanford/stanford-bunny.obj.zst", 256},
                                                          {"classic/teapot.obj", 128},
                                                          {"assimp/OBJ/spider.obj", 64}}) {
    const Voxels v = voxelize_surface(corpus(mesh), {n, false, 2});
    expect_dag_of(v.codes, n, mesh);
  }
}

TEST(VoxelDag, RefusesEmptyAndOutOfGridCodes) {
  EXPECT_THROW(build_voxel_dag(std::vector<std::uint64_t>{}, 8), std::invalid_argument);
  EXPECT_THROW(build_voxel_dag(std::vector<std::uint64_t>{512}, 8), std::invalid_argument);
  EXPECT_THROW(build_voxel_dag(std::vector<std::uint64_t>{0, 4096}, 16), std::invalid_argument);
  EXPECT_THROW(build_voxel_dag(std::vector<std::uint64_t>{1, std::uint64_t{1} << 42}, 8192),
               std::invalid_argument);
  EXPECT_NO_THROW(build_voxel_dag(std::vector<std::uint64_t>{511}, 8));
}

TEST(VoxelDag, DeterministicWords) {
  std::mt19937_64 rng(9);
  std::vector<std::uint64_t> codes;
  for (int i = 0; i < 20000; ++i) codes.push_back(rng() % (std::uint64_t{1} << 27));
  codes = sorted_unique(codes);
  const FlatVoxelDag a = build_voxel_dag(codes, 512), b = build_voxel_dag(codes, 512);
  EXPECT_TRUE(a.words == b.words);
  EXPECT_TRUE(build_voxel_dag(leaves_of(codes), 512).words == a.words);
  EXPECT_EQ(a.svo_bytes, b.svo_bytes);
  for (std::size_t l = 0; l < a.level_stats.size(); ++l) {
    EXPECT_EQ(a.level_stats[l].dag_nodes, b.level_stats[l].dag_nodes);
    EXPECT_EQ(a.level_stats[l].first_word, b.level_stats[l].first_word);
  }
  KILN_REQUIRE_CORPUS();
  for (const auto& [mesh, n] : std::vector<std::pair<const char*, std::uint32_t>>{
           {"stanford/stanford-bunny.obj.zst", 256}, {"classic/spot.obj", 128}}) {
    const Scene scene = corpus(mesh);
    const FlatVoxelDag one = build_voxel_dag(voxelize_surface(scene, {n, false, 1}).codes, n);
    for (const unsigned threads : {2u, 8u}) {
      const FlatVoxelDag other =
          build_voxel_dag(voxelize_surface(scene, {n, false, threads}).codes, n);
      EXPECT_TRUE(other.words == one.words) << mesh << ", " << threads << " threads";
      EXPECT_EQ(other.dag_bytes, one.dag_bytes);
    }
  }
}

}  // namespace
}  // namespace kiln
