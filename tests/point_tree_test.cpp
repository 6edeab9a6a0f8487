// The point k-d tree against brute force (kNN and radius, ties by id) on corpus meshes' vertices
// and generated worst cases; point-cloud import; layout checks, determinism, the command line.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/compiler/point_tree_builder.hpp"
#include "kiln/runtime/aligned_buffer.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/point_tree.hpp"
#include "kiln/runtime/ray.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

using format::Float3;
using namespace kiln::test;

struct BuiltPointTree {
  FlatPointTree flat;
  PointTreeView view() const {
    return PointTreeView(flat.nodes, flat.points, flat.ids, flat.bounds);
  }
};

BuiltPointTree build(std::span<const Float3> points, PointSplitRule rule, std::uint32_t leaf) {
  PointTreeBuildOptions o;
  o.split = rule;
  o.max_leaf_size = leaf;
  return {build_point_tree(points, o)};
}

// Every point's distance, computed as the runtime documents it, sorted by (distance, id).
std::vector<Neighbor> brute_force(std::span<const Float3> points, const Float3& q) {
  std::vector<Neighbor> all(points.size());
  for (std::uint32_t i = 0; i < points.size(); ++i) {
    const float dx = points[i].x - q.x, dy = points[i].y - q.y, dz = points[i].z - q.z;
    all[i] = {i, (dx * dx + dy * dy) + dz * dz};
  }
  std::sort(all.begin(), all.end(), closer);
  return all;
}

// Queries: on points exactly (zero distances, duplicates), jittered near them, and uniform in
// the bounds grown by half their size (far ones included).
std::vector<Float3> sample_queries(std::span<const Float3> points, std::size_t count,
                                   std::uint32_t seed) {
  std::mt19937 rng(seed);
  const format::Box3f b = bounds_of(points);
  const float size = std::max({b.max.x - b.min.x, b.max.y - b.min.y, b.max.z - b.min.z, 1e-3f});
  std::uniform_real_distribution<float> unit(0, 1), jitter(-0.01f * size, 0.01f * size);
  std::uniform_int_distribution<std::size_t> pick(0, points.size() - 1);
  std::vector<Float3> queries;
  for (std::size_t i = 0; i < count; ++i) {
    const Float3 p = points[pick(rng)];
    if (i % 3 == 0) {
      queries.push_back(p);
    } else if (i % 3 == 1) {
      queries.push_back({p.x + jitter(rng), p.y + jitter(rng), p.z + jitter(rng)});
    } else {
      auto along = [&](float lo, float hi) {
        return lo - 0.5f * (hi - lo) + 2.0f * (hi - lo) * unit(rng);
      };
      queries.push_back(
          {along(b.min.x, b.max.x), along(b.min.y, b.max.y), along(b.min.z, b.max.z)});
    }
  }
  return queries;
}

// kNN for k = 1, 8, 32 and radius searches at two radii: the same lists as brute force.
void expect_matches_brute_force(std::span<const Float3> points, const PointTreeView& tree,
                                std::size_t query_count, const std::string& what) {
  const format::Box3f b = bounds_of(points);
  const float diagonal = std::hypot(b.max.x - b.min.x, b.max.y - b.min.y, b.max.z - b.min.z);
  std::size_t mismatches = 0;
  std::vector<Neighbor> found, within;
  for (const Float3& q : sample_queries(points, query_count, 7)) {
    const auto all = brute_force(points, q);
    for (const std::size_t k : {1, 8, 32}) {
      found.assign(k, Neighbor{});
      const std::size_t n = tree.nearest(q, found);
      const std::size_t expected_n = std::min(k, all.size());
      if (n != expected_n) {
        mismatches += 1;
        continue;
      }
      for (std::size_t i = 0; i < n; ++i)
        mismatches += found[i].id != all[i].id || found[i].distance2 != all[i].distance2;
    }
    for (const float fraction : {0.002f, 0.03f}) {
      const float radius = fraction * diagonal;
      tree.within_radius(q, radius, within);
      std::size_t expected = 0;
      while (expected < all.size() && all[expected].distance2 <= radius * radius) ++expected;
      if (within.size() != expected) {
        mismatches += 1;
        continue;
      }
      for (std::size_t i = 0; i < expected; ++i) mismatches += within[i].id != all[i].id;
    }
  }
  EXPECT_EQ(mismatches, 0u) << what;
}

void expect_well_formed(const FlatPointTree& flat, std::size_t n, std::uint32_t leaf) {
  std::vector<std::uint32_t> ids = flat.ids;
  std::sort(ids.begin(), ids.end());
  for (std::uint32_t i = 0; i < n; ++i) ASSERT_EQ(ids[i], i);  // every point exactly once
  EXPECT_LE(flat.stats.max_depth, format::kPointMaxDepth);
  for (const auto& node : flat.nodes)
    if (node.is_leaf() && node.point_count() > leaf) {
      // Only identical points may exceed the leaf size.
      const Float3 first = flat.points[node.first_point()];
      for (std::uint32_t i = 0; i < node.point_count(); ++i)
        EXPECT_EQ(std::memcmp(&flat.points[node.first_point() + i], &first, sizeof first), 0);
    }
}

Scene corpus_scene(const std::string& mesh) {
  return import_scene({mesh_path(mesh)}, 2);
}

TEST(PointTree, NearestAndRadiusMatchBruteForceOnCorpusVertices) {
  KILN_REQUIRE_CORPUS();
  for (const char* mesh :
       {"classic/teapot.obj", "stanford/stanford-bunny.obj.zst", "assimp/OBJ/spider.obj"}) {
    const Scene scene = corpus_scene(mesh);
    for (const auto rule : {PointSplitRule::kMedian, PointSplitRule::kSlidingMidpoint})
      for (const std::uint32_t leaf : {1u, 10u, 32u}) {
        const auto built = build(scene.positions, rule, leaf);
        expect_well_formed(built.flat, scene.positions.size(), leaf);
        expect_matches_brute_force(
            scene.positions, built.view(), 300,
            std::string(mesh) + " " + to_string(rule) + " leaf " + std::to_string(leaf));
      }
  }
}

TEST(PointTree, TiesGoToTheLowerIdOnGridsAndDuplicates) {
  // An integer grid: most queries have many neighbours at exactly equal distances. Every grid
  // point is stored three times, so zero-distance ties are three-way.
  std::vector<Float3> grid;
  for (int copy = 0; copy < 3; ++copy)
    for (int x = 0; x < 12; ++x)
      for (int y = 0; y < 12; ++y)
        for (int z = 0; z < 12; ++z) grid.push_back({float(x), float(y), float(z)});
  for (const auto rule : {PointSplitRule::kMedian, PointSplitRule::kSlidingMidpoint})
    for (const std::uint32_t leaf : {1u, 4u, 10u}) {
      const auto built = build(grid, rule, leaf);
      expect_well_formed(built.flat, grid.size(), leaf);
      expect_matches_brute_force(grid, built.view(), 600, "grid " + to_string(rule));
    }
}

TEST(PointTree, WorstCaseDistributions) {
  std::mt19937 rng(3);
  std::normal_distribution<float> normal(0, 1);
  std::vector<std::pair<std::string, std::vector<Float3>>> cases;
  cases.push_back({"one point", {{1, 2, 3}}});
  cases.push_back({"identical", std::vector<Float3>(5000, Float3{0.25f, -1, 7})});
  std::vector<Float3> exponential;  // sliding midpoint peels one point per level
  for (int i = 0; i < 200; ++i) exponential.push_back({std::ldexp(1.0f, i - 100), 0, 0});
  cases.push_back({"exponential", exponential});
  std::vector<Float3> clusters;  // two tight clusters far apart, and a line
  for (int i = 0; i < 3000; ++i) {
    const float offset = i % 2 ? 1e6f : -1e6f;
    clusters.push_back({offset + 1e-3f * normal(rng), 1e-3f * normal(rng), 1e-3f * normal(rng)});
  }
  for (int i = 0; i < 1000; ++i) clusters.push_back({0, float(i), 0});
  cases.push_back({"clusters", clusters});
  std::vector<Float3> plane;  // flat: one axis has no extent
  for (int i = 0; i < 4000; ++i) plane.push_back({normal(rng), normal(rng), 5});
  cases.push_back({"plane", plane});
  for (const auto& [name, points] : cases)
    for (const auto rule : {PointSplitRule::kMedian, PointSplitRule::kSlidingMidpoint})
      for (const std::uint32_t leaf : {1u, 10u}) {
        const auto built = build(points, rule, leaf);
        expect_well_formed(built.flat, points.size(), leaf);
        expect_matches_brute_force(points, built.view(), 300, name + " " + to_string(rule));
      }
}

TEST(PointTree, FewerPointsThanKAndEmptyOutputs) {
  const std::vector<Float3> points = {{0, 0, 0}, {1, 0, 0}, {0, 2, 0}};
  const auto built = build(points, PointSplitRule::kMedian, 1);
  std::vector<Neighbor> found(8, Neighbor{kNoHit, -1});
  ASSERT_EQ(built.view().nearest({0.9f, 0, 0}, found), 3u);
  EXPECT_EQ(found[0].id, 1u);
  EXPECT_EQ(found[1].id, 0u);
  EXPECT_EQ(found[2].id, 2u);
  EXPECT_EQ(found[3].id, kNoHit);  // untouched
  EXPECT_EQ(built.view().nearest({0, 0, 0}, std::span<Neighbor>()), 0u);
  std::vector<Neighbor> within{{5, 5}};
  built.view().within_radius({10, 10, 10}, 1.0f, within);
  EXPECT_TRUE(within.empty());
  built.view().within_radius({0, 0, 0}, 1.0f, within);  // the boundary counts
  ASSERT_EQ(within.size(), 2u);
  EXPECT_EQ(within[1].id, 1u);
  EXPECT_THROW(build({}, PointSplitRule::kMedian, 10), std::invalid_argument);
  EXPECT_THROW(build(points, PointSplitRule::kMedian, 0), std::invalid_argument);
}

Scene point_scene(std::size_t count, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(-1, 1);
  Scene scene;
  for (std::size_t i = 0; i < count; ++i)
    scene.positions.push_back({unit(rng), unit(rng), unit(rng)});
  scene.bounds = bounds_of(scene.positions);
  scene.sources.push_back({"generated", 0, 0});
  scene.meshes.push_back({"cloud", 0, 0, 0, 0, count});
  return scene;
}

std::vector<std::byte> points_blob(const Scene& scene, unsigned threads, bool compress = false) {
  BuildOptions options;
  options.inputs = {"generated"};
  options.threads = threads;
  options.compression.enabled = compress;
  options.structures.push_back(resolve_structure_request("points", {}));
  return compile_blob(scene, options);
}

TEST(PointTree, BuildsAreByteIdenticalAcrossThreadCountsAndRoundTrip) {
  const Scene scene = point_scene(150000, 11);  // above the parallel threshold
  const auto one = points_blob(scene, 1);
  EXPECT_EQ(one, points_blob(scene, 2));
  EXPECT_EQ(one, points_blob(scene, 8));
  EXPECT_EQ(open_and_verify(one), "");
  const auto compressed = points_blob(scene, 2, true);
  EXPECT_EQ(open_and_verify(compressed), "");
  const auto direct = build(scene.positions, PointSplitRule::kSlidingMidpoint, 10);
  for (const auto* bytes : {&one, &compressed}) {
    const AlignedBuffer aligned = aligned_copy(*bytes);
    const Blob blob = Blob::open_memory(aligned.bytes());
    const PointTreeView view = PointTreeView::from_blob(blob);
    std::vector<Neighbor> a(16), b(16);
    for (const Float3& q : sample_queries(scene.positions, 200, 5)) {
      view.nearest(q, a);
      direct.view().nearest(q, b);
      ASSERT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(Neighbor)), 0);
    }
  }
}

TEST(PointTree, CorruptedArraysAreRefused) {
  const Scene scene = point_scene(5000, 2);
  const auto blob = points_blob(scene, 2);
  const AlignedBuffer aligned = aligned_copy(blob);
  const Blob original = Blob::open_memory(aligned.bytes());
  const StructureInfo* points = original.structure("points");
  ASSERT_NE(points, nullptr);
  const auto* desc = &desc_of<schema::PointTreeDesc>(original, *points);
  const auto nodes = original.section_view<format::PointNode>(desc->nodes());
  ASSERT_FALSE(nodes[0].is_leaf());
  std::uint32_t leaf = 0;
  while (!nodes[leaf].is_leaf()) ++leaf;
  auto forge = [&](std::uint32_t section, std::size_t offset, const auto& value) {
    return forged_copy(blob, section, offset, value);
  };
  auto expect_refused = [&](const AlignedBuffer& copy, const char* what) {
    const Blob b = Blob::open_memory(copy.bytes());
    EXPECT_THROW(PointTreeView::from_blob(b), BlobError) << what;
    EXPECT_THROW(b.verify(), BlobError) << what;
  };
  const auto root = nodes[0];
  expect_refused(
      forge(desc->nodes(), 0,
            format::PointNode::interior(0, root.below_max(), root.above_min(), 0x3FFFFF00u)),
      "child out of range");
  expect_refused(forge(desc->nodes(), 0,
                       format::PointNode::interior(1, root.below_max(), root.above_min(), 0)),
                 "cycle");
  expect_refused(forge(desc->nodes(), leaf * sizeof(format::PointNode),
                       format::PointNode::leaf(nodes[leaf].first_point(), 0xFFFFFFF0u)),
                 "leaf range");
  // Layout intact, contents wrong: only the deep check sees these.
  auto expect_verify_refuses = [&](const AlignedBuffer& copy, const char* what) {
    const Blob b = Blob::open_memory(copy.bytes());
    EXPECT_NO_THROW(PointTreeView::from_blob(b)) << what;
    EXPECT_THROW(b.verify(), BlobError) << what;
  };
  expect_verify_refuses(forge(desc->point_ids(), 0, std::uint32_t{1}), "duplicate id");
  expect_verify_refuses(forge(desc->point_ids(), 0, std::uint32_t{0xFFFFFF00u}), "id range");
  expect_verify_refuses(forge(desc->points(), 0, Float3{9, 9, 9}), "moved point");
  expect_verify_refuses(forge(desc->nodes(), 0,
                              format::PointNode::interior(int(root.axis()), root.above_min() + 1,
                                                          root.above_min(), root.above_child())),
                        "inverted gap");
}

TEST(PointTree, PointCloudsImportForThePointTreeAlone) {
  KILN_REQUIRE_CORPUS();
  const Scene ply = corpus_scene("assimp/PLY/points.ply");
  EXPECT_EQ(ply.triangles.size(), 0u);
  ASSERT_EQ(ply.positions.size(), 4u);
  EXPECT_EQ(ply.positions[3].y, 1.0f);
  EXPECT_EQ(ply.positions[3].z, 1.0f);
  EXPECT_EQ(corpus_scene("assimp/OBJ/point_cloud.obj").positions.size(), 3u);
  EXPECT_EQ(corpus_scene("assimp/OBJ/testpoints.obj").positions.size(), 8u);
  // Lines are neither a surface nor a cloud.
  EXPECT_THROW(corpus_scene("assimp/OBJ/testline.obj"), ImportError);

  TempDir dir;
  const std::string cloud = quoted(mesh_path("assimp/PLY/points.ply"));
  const std::string out = dir.file("p.kiln");
  ASSERT_EQ(run_kiln("build " + cloud + " --accel points -o " + quoted(out)).exit_code, 0);
  EXPECT_EQ(run_kiln("verify " + quoted(out)).exit_code, 0);
  const auto dump = run_kiln("dump --json " + quoted(out));
  EXPECT_NE(dump.out.find("\"point_count\":4"), std::string::npos) << dump.out;
  for (const char* others : {" --accel points --accel bvh", " --accel kdtree", ""}) {
    const auto refused = run_kiln("build " + cloud + others + " -o " + quoted(dir.file("x.kiln")));
    EXPECT_EQ(refused.exit_code, 1) << others;
    EXPECT_NE(refused.err.find("no triangles"), std::string::npos) << refused.err;
    EXPECT_FALSE(std::filesystem::exists(dir.file("x.kiln")));
  }
}

TEST(PointTree, CommandLineKnnAndRadius) {
  KILN_REQUIRE_CORPUS();
  TempDir dir;
  const std::string blob = dir.file("t.kiln"), in = dir.file("q.bin");
  ASSERT_EQ(
      run_kiln("build " + quoted(mesh_path("classic/teapot.obj")) +
               " --accel points --points-split median --points-leaf-size 4 -o " + quoted(blob))
          .exit_code,
      0);
  const Scene scene = corpus_scene("classic/teapot.obj");
  const auto queries = sample_queries(scene.positions, 500, 9);
  write_file(in, std::as_bytes(std::span(queries)));
  constexpr std::uint32_t k = 5;
  ASSERT_EQ(run_kiln("query " + quoted(blob) + " --op knn --k 5 --in " + quoted(in) + " --out " +
                     quoted(dir.file("knn.bin")) + " --threads 2")
                .exit_code,
            0);
  const auto knn = read_file(dir.file("knn.bin"));
  ASSERT_EQ(knn.size(), queries.size() * k * sizeof(Neighbor));
  const float radius = 0.05f;
  ASSERT_EQ(run_kiln("query " + quoted(blob) + " --op radius --radius 0.05 --in " + quoted(in) +
                     " --out " + quoted(dir.file("r.bin")))
                .exit_code,
            0);
  const auto within = read_file(dir.file("r.bin"));
  std::size_t offset = 0, mismatches = 0;
  for (std::size_t i = 0; i < queries.size(); ++i) {
    const auto all = brute_force(scene.positions, queries[i]);
    for (std::uint32_t j = 0; j < k; ++j) {
      Neighbor n;
      std::memcpy(&n, knn.data() + (i * k + j) * sizeof n, sizeof n);
      mismatches += n.id != all[j].id || n.distance2 != all[j].distance2;
    }
    std::uint32_t count = 0;
    ASSERT_LE(offset + 4, within.size());
    std::memcpy(&count, within.data() + offset, 4);
    offset += 4;
    std::size_t expected = 0;
    while (expected < all.size() && all[expected].distance2 <= radius * radius) ++expected;
    mismatches += count != expected;
    ASSERT_LE(offset + 4 * count, within.size());
    for (std::uint32_t j = 0; j < count && j < expected; ++j) {
      std::uint32_t id = 0;
      std::memcpy(&id, within.data() + offset + 4 * j, 4);
      mismatches += id != all[j].id;
    }
    offset += 4 * count;
  }
  EXPECT_EQ(offset, within.size());
  EXPECT_EQ(mismatches, 0u);

  // Malformed input and a blob without a point tree: one line, exit 1, no output.
  write_file(dir.file("bad.bin"), std::as_bytes(std::span(queries).first(1)).first(10));
  auto result = run_kiln("query " + quoted(blob) + " --op knn --k 2 --in " +
                         quoted(dir.file("bad.bin")) + " --out " + quoted(dir.file("x.bin")));
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.err.find("multiple of 12"), std::string::npos) << result.err;
  EXPECT_FALSE(std::filesystem::exists(dir.file("x.bin")));
  ASSERT_EQ(run_kiln("build " + quoted(mesh_path("classic/teapot.obj")) + " --accel bvh -o " +
                     quoted(dir.file("bvh.kiln")))
                .exit_code,
            0);
  result = run_kiln("query " + quoted(dir.file("bvh.kiln")) + " --op radius --radius 1 --in " +
                    quoted(in) + " --out " + quoted(dir.file("x.bin")));
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.err.find("holds no structure that can answer nearest-neighbour queries"),
            std::string::npos)
      << result.err;
  EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << result.err;
  EXPECT_FALSE(std::filesystem::exists(dir.file("x.bin")));
  result = run_kiln("build " + quoted(mesh_path("classic/teapot.obj")) +
                    " --accel points --points-leaf-size 0 -o " + quoted(dir.file("y.kiln")));
  EXPECT_NE(result.exit_code, 0);
  EXPECT_NE(result.err.find("--points-leaf-size"), std::string::npos) << result.err;
  EXPECT_FALSE(std::filesystem::exists(dir.file("y.kiln")));
}

}  // namespace
}  // namespace kiln
