// The out-of-core voxel DAG build (issue 20): byte-identical to the in-core build whatever the
// cut into sub-cubes and the thread count, the in-core build against an independent reference,
// peak memory of `kiln build` under --memory-budget, and casts at 131,072^3.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include "kiln/bench/generated_scenes.hpp"
#include "kiln/compiler/build.hpp"
#include "kiln/compiler/voxel_dag_builder.hpp"
#include "kiln/compiler/voxelizer.hpp"
#include "kiln/formats/voxel_grid.hpp"
#include "kiln/runtime/voxel_dag.hpp"
#include "test_support.hpp"
#include "voxel_fixtures.hpp"

namespace kiln {
namespace {

using format::Float3;
using test::scene_of;
using test::slivers;

Scene generated(const bench::GeneratedMesh& mesh) {
  return scene_of(mesh.positions, mesh.triangles);
}

// The DAG words by the format's definition alone (docs/FORMAT.md), with ordered maps: nodes
// merged by (mask, children), ids by first occurrence in Morton order, levels top down, leaves
// last. The independent reference of the in-core build.
std::vector<std::uint32_t> reference_words(const std::vector<std::uint64_t>& codes,
                                           std::uint32_t resolution) {
  const int levels = std::countr_zero(resolution), leaf_level = levels - 2;
  std::map<std::uint64_t, std::uint64_t> blocks;  // key -> mask, in Morton order
  for (const std::uint64_t c : codes) blocks[c >> 6] |= std::uint64_t(1) << (c & 63);
  std::map<std::uint64_t, std::uint32_t> leaf_ids;
  std::vector<std::uint64_t> leaf_masks;
  std::vector<std::pair<std::uint64_t, std::uint32_t>> below;  // key, id at the level below
  for (const auto& [key, mask] : blocks) {
    const auto [it, fresh] = leaf_ids.emplace(mask, std::uint32_t(leaf_masks.size()));
    if (fresh) leaf_masks.push_back(mask);
    below.push_back({key, it->second});
  }
  using Node = std::array<std::uint32_t, 9>;  // mask, then child ids (absent: ~0)
  std::vector<std::vector<Node>> unique(leaf_level);
  for (int level = leaf_level - 1; level >= 0; --level) {
    std::map<std::uint64_t, Node> parents;
    for (const auto& [key, id] : below) {
      auto [it, fresh] = parents.try_emplace(key >> 3);
      if (fresh) it->second.fill(~0u), it->second[0] = 0;
      it->second[0] |= 1u << (key & 7);
      it->second[1 + (key & 7)] = id;
    }
    std::map<Node, std::uint32_t> ids;
    below.clear();
    for (const auto& [key, node] : parents) {
      const auto [it, fresh] = ids.emplace(node, std::uint32_t(unique[level].size()));
      if (fresh) unique[level].push_back(node);
      below.push_back({key, it->second});
    }
  }
  std::vector<std::vector<std::uint32_t>> first(leaf_level + 1);
  std::uint32_t word = 0;
  for (int level = 0; level < leaf_level; ++level)
    for (const Node& n : unique[level])
      first[level].push_back(word), word += 1 + std::popcount(n[0]);
  for (std::size_t i = 0; i < leaf_masks.size(); ++i) first[leaf_level].push_back(word + 2 * i);
  std::vector<std::uint32_t> words;
  for (int level = 0; level < leaf_level; ++level)
    for (const Node& n : unique[level]) {
      words.push_back(n[0]);
      for (int octant = 0; octant < 8; ++octant)
        if (n[0] >> octant & 1) words.push_back(first[level + 1][n[1 + octant]]);
    }
  for (const std::uint64_t mask : leaf_masks)
    words.push_back(std::uint32_t(mask)), words.push_back(std::uint32_t(mask >> 32));
  return words;
}

FlatVoxelDag in_core(const Scene& scene, std::uint32_t n) {
  return build_voxel_dag(voxelize_surface(scene, {n, false, 2}).codes, n);
}

FlatVoxelDag out_of_core(const Scene& scene, std::uint32_t n, std::uint32_t cube_side,
                         unsigned threads, OutOfCoreDagStats* stats = nullptr) {
  OutOfCoreDagOptions options;
  options.cube_side = cube_side;
  options.threads = threads;
  return build_voxel_dag_out_of_core(scene, fit_voxel_grid(scene.bounds, n), options, stats);
}

void expect_same(const FlatVoxelDag& a, const FlatVoxelDag& b, const std::string& what) {
  EXPECT_TRUE(a.words == b.words) << what;
  EXPECT_EQ(a.voxel_count, b.voxel_count) << what;
  EXPECT_EQ(a.svo_bytes, b.svo_bytes) << what;
  EXPECT_EQ(a.leaf_first_word, b.leaf_first_word) << what;
  ASSERT_EQ(a.level_stats.size(), b.level_stats.size()) << what;
  for (std::size_t l = 0; l < a.level_stats.size(); ++l) {
    EXPECT_EQ(a.level_stats[l].svo_nodes, b.level_stats[l].svo_nodes) << what << " level " << l;
    EXPECT_EQ(a.level_stats[l].dag_nodes, b.level_stats[l].dag_nodes) << what << " level " << l;
    EXPECT_EQ(a.level_stats[l].first_word, b.level_stats[l].first_word) << what << " level " << l;
    EXPECT_EQ(a.level_stats[l].bytes, b.level_stats[l].bytes) << what << " level " << l;
  }
}

// In-core vs out-of-core with grids of 8, 64 and 512 cubes (only the non-empty ones are built).
void expect_cuts_agree(const Scene& scene, std::uint32_t n, const std::string& name) {
  const FlatVoxelDag reference = in_core(scene, n);
  for (const std::uint32_t cubes_per_axis : {2u, 4u, 8u}) {
    OutOfCoreDagStats stats;
    const FlatVoxelDag dag = out_of_core(scene, n, n / cubes_per_axis, 2, &stats);
    const std::string what = name + " " + std::to_string(n) + "^3 in " +
                             std::to_string(cubes_per_axis * cubes_per_axis * cubes_per_axis) +
                             " cubes";
    expect_same(dag, reference, what);
    EXPECT_GT(stats.cubes, 1u) << what;
    EXPECT_LE(stats.cubes, std::uint64_t(cubes_per_axis) * cubes_per_axis * cubes_per_axis) << what;
    EXPECT_EQ(stats.largest_side, n / cubes_per_axis) << what;
    EXPECT_EQ(stats.smallest_side, n / cubes_per_axis) << what;
  }
}

TEST(VoxelDagOutOfCore, InCoreBuildMatchesTheFormatsDefinition) {
  const Scene scene = generated(bench::teapot_in_stadium(3000, 7));
  for (const std::uint32_t n : {8u, 64u, 256u}) {
    const auto codes = voxelize_surface(scene, {n, false, 2}).codes;
    EXPECT_TRUE(build_voxel_dag(codes, n).words == reference_words(codes, n)) << n;
  }
  const auto codes = voxelize_surface(slivers(), {2048, false, 2}).codes;
  EXPECT_TRUE(build_voxel_dag(codes, 2048).words == reference_words(codes, 2048));
}

TEST(VoxelDagOutOfCore, ByteIdenticalToInCoreOnGeneratedScenes) {
  expect_cuts_agree(generated(bench::teapot_in_stadium(3000, 3)), 256, "teapot-in-stadium");
  expect_cuts_agree(generated(bench::uniform_triangles(400, 5)), 256, "uniform-triangles");
  expect_cuts_agree(slivers(), 2048, "slivers");
}

TEST(VoxelDagOutOfCore, ByteIdenticalToInCoreOnTheCorpus) {
  KILN_REQUIRE_CORPUS();
  expect_cuts_agree(import_scene({test::mesh_path("stanford/stanford-bunny.obj.zst")}, 2), 256,
                    "bunny");
  expect_cuts_agree(import_scene({test::mesh_path("stanford/dragon_100k.obj.zst")}, 2), 256,
                    "dragon");
}

TEST(VoxelDagOutOfCore, IndependentOfThreadsAndBudget) {
  const Scene scene = generated(bench::teapot_in_stadium(3000, 11));
  const std::uint32_t n = 512;
  const FlatVoxelDag reference = out_of_core(scene, n, 0, 1);
  for (const unsigned threads : {2u, 8u})
    for (const std::uint32_t side : {0u, 128u, 64u})
      expect_same(out_of_core(scene, n, side, threads), reference,
                  std::to_string(threads) + " threads, side " + std::to_string(side));
  // A budget too small for the whole grid cuts it by itself, down to 64^3 cubes where needed.
  OutOfCoreDagOptions tight;
  tight.memory_budget = 1 << 20;
  OutOfCoreDagStats stats;
  expect_same(build_voxel_dag_out_of_core(scene, fit_voxel_grid(scene.bounds, n), tight, &stats),
              reference, "1 MiB budget");
  EXPECT_GT(stats.cubes, 8u);
  EXPECT_EQ(stats.smallest_side, 64u);
  // The default budget holds this grid whole: one cube, the in-core case.
  out_of_core(scene, n, 0, 2, &stats);
  EXPECT_EQ(stats.cubes, 1u);
  EXPECT_EQ(stats.largest_side, n);
}

TEST(VoxelDagOutOfCore, ProgressCountsEveryCube) {
  const Scene scene = generated(bench::teapot_in_stadium(2000, 13));
  OutOfCoreDagOptions options;
  options.cube_side = 32;
  std::vector<std::pair<std::uint64_t, double>> calls;
  std::uint64_t planned = 0;
  options.progress = [&](std::uint64_t done, std::uint64_t total, double share) {
    calls.push_back({done, share});
    planned = total;
  };
  OutOfCoreDagStats stats;
  build_voxel_dag_out_of_core(scene, fit_voxel_grid(scene.bounds, 256), options, &stats);
  ASSERT_EQ(calls.size(), stats.cubes);
  EXPECT_EQ(planned, stats.cubes);
  for (std::size_t i = 0; i < calls.size(); ++i) {
    EXPECT_EQ(calls[i].first, i + 1);
    if (i > 0) {
      EXPECT_GE(calls[i].second, calls[i - 1].second);
    }
  }
  EXPECT_DOUBLE_EQ(calls.back().second, 1.0);
}

TEST(VoxelDagOutOfCore, RefusesBadCubeSidesAndEmptyGrids) {
  const Scene scene = slivers();
  for (const std::uint32_t side : {2u, 48u, 512u})
    EXPECT_THROW(out_of_core(scene, 256, side, 1), std::invalid_argument) << side;
  EXPECT_THROW(out_of_core(scene_of({}, {}), 256, 0, 1), std::invalid_argument);
}

// The slivers at 131,072^3 (17 levels), cut into 2048^3 cubes: casts straight down voxel columns
// return the column's highest voxel that the triangles touch (brute force over the column's
// 131,072 voxels), and occupancy agrees around it.
TEST(VoxelDagOutOfCore, CastsAndOccupancyAt131072) {
  const Scene scene = slivers();
  const std::uint32_t n = format::kVoxelMaxResolution;
  const VoxelGrid grid = fit_voxel_grid(scene.bounds, n);
  const FlatVoxelDag dag = out_of_core(scene, n, 2048, 2);
  EXPECT_EQ(dag.levels, 17u);
  const VoxelDagView view(dag.words, frame_of(grid), level_first_words(dag), dag.leaf_first_word,
                          {}, {});
  std::vector<GridTriangle> triangles;
  for (const auto& t : scene.triangles)
    triangles.push_back(
        to_grid(grid, scene.positions[t.v[0]], scene.positions[t.v[1]], scene.positions[t.v[2]]));
  const auto touched = [&](std::uint32_t x, std::uint32_t y, std::uint32_t z) {
    for (const GridTriangle& t : triangles)
      if (triangle_touches_voxel(t, x, y, z)) return true;
    return false;
  };
  // Columns over the x sliver (y = 0), over the z sliver's top, and one beside it.
  const std::array<std::array<std::uint32_t, 2>, 7> columns{
      {{5, 0}, {1000, 0}, {65535, 0}, {65536, 0}, {131071, 0}, {65536, 65536}, {65540, 65536}}};
  for (const auto& [x, y] : columns) {
    std::uint32_t expected = kNoHit;
    for (std::uint32_t z = n; z-- > 0 && expected == kNoHit;)
      if (touched(x, y, z)) expected = z;
    Ray ray;
    ray.org = {float(grid.origin[0] + (x + 0.5) * grid.voxel_size),
               float(grid.origin[1] + (y + 0.5) * grid.voxel_size), 2.0f};
    ray.dir = {0, 0, -1};
    ray.tmin = 0, ray.tmax = 10;
    const VoxelHit hit = view.intersect(ray);
    const std::string what = std::to_string(x) + "," + std::to_string(y);
    EXPECT_EQ(hit.z, expected) << what;
    if (expected == kNoHit) continue;
    EXPECT_EQ(hit.x, x) << what;
    EXPECT_EQ(hit.y, y) << what;
    for (std::uint32_t z = expected >= 3 ? expected - 3 : 0; z <= std::min(n - 1, expected + 3);
         ++z)
      EXPECT_EQ(view.occupied(x, y, z), touched(x, y, z)) << what << " z " << z;
  }
}

// The peak resident size of one `kiln build`, in KiB, or -1 when it failed. A child forked from
// this (large) test process would count this process's pages in its own peak, even across exec,
// so a small Python process starts the build and reports getrusage(RUSAGE_CHILDREN).
long peak_rss_kib(const std::string& arguments) {
  test::TempDir dir;
  const std::string out = dir.file("peak");
  const std::string command =
      "/usr/bin/python3 -c 'import resource, subprocess, sys; "
      "r = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL).returncode; "
      "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss if r == 0 else -1)' " +
      test::quoted(KILN_CLI) + " " + arguments + " > " + test::quoted(out);
  if (std::system(command.c_str()) != 0) return -1;
  return std::stol(test::read_text(out));
}

// The bunny at 1024^3 (3.6 M surface voxels; in core the build peaks near 90 MiB) under a
// 24 MiB budget stays under the budget plus 24 MiB of slack (the process itself: code, the
// imported mesh, the blob being written: about 28 MiB whatever the budget), and writes the same
// file as the default build, which holds the whole grid at once.
TEST(VoxelDagOutOfCore, PeakMemoryFollowsTheBudget) {
  KILN_REQUIRE_CORPUS();
  if (test::kSanitized) GTEST_SKIP() << "resident sizes mean nothing under AddressSanitizer";
  test::TempDir dir;
  const std::string mesh = test::mesh_path("stanford/stanford-bunny.obj.zst");
  if (access("/usr/bin/python3", X_OK) != 0) GTEST_SKIP() << "/usr/bin/python3 is absent";
  const auto build = [&](const std::string& out, const std::string& budget) {
    const long kib = peak_rss_kib("build " + test::quoted(mesh) +
                                  " --accel dag --resolution 1024 --threads 2 --memory-budget " +
                                  budget + " -o " + test::quoted(out));
    EXPECT_GT(kib, 0) << budget;
    return kib;
  };
  const long small = build(dir.file("small.kiln"), "24M");
  const long whole = build(dir.file("whole.kiln"), "auto");
  EXPECT_LE(small, (24 + 24) * 1024) << "peak KiB under a 24 MiB budget; whole grid: " << whole;
  EXPECT_LT(small, whole);
  EXPECT_TRUE(test::read_file(dir.file("small.kiln")) == test::read_file(dir.file("whole.kiln")));
}

TEST(VoxelDagOutOfCore, CommandLineRefusesWhatStaysInCore) {
  test::TempDir dir;
  const std::string out = " -o " + test::quoted(dir.file("never.kiln"));
  const auto esvo = test::run_kiln("build /dev/null --accel esvo --resolution 32768" + out);
  EXPECT_NE(esvo.exit_code, 0);
  EXPECT_NE(esvo.err.find("8..16384"), std::string::npos) << esvo.err;
  // --solid needs every surface voxel at once (one triangle: the input is not what fails).
  const std::string triangle = dir.file("triangle.obj");
  test::write_text(triangle, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  for (const char* kind : {"dag", "ssvdag"}) {
    const auto solid = test::run_kiln("build " + test::quoted(triangle) + " --accel " + kind +
                                      " --solid --resolution 32768" + out);
    EXPECT_NE(solid.exit_code, 0) << kind;
    EXPECT_NE(solid.err.find("up to --resolution 16384"), std::string::npos) << solid.err;
  }
  const auto budget = test::run_kiln("build /dev/null --accel dag --memory-budget 12Q" + out);
  EXPECT_NE(budget.exit_code, 0);
  EXPECT_NE(budget.err.find("unknown unit"), std::string::npos) << budget.err;
  EXPECT_NE(test::run_kiln("build /dev/null --accel dag --resolution 262144" + out).exit_code, 0);
}

}  // namespace
}  // namespace kiln
