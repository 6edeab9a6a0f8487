// ESVO: with contours off the hits are the voxel DAG's on the same voxel set; with contours on
// every hit lies within the error bound of a triangle (closest point on a BVH), and the hit/miss
// disagreement with the exact mesh is below the cubes'; blobs are deterministic, round trip and
// refuse corrupted descriptors.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/compiler/esvo_builder.hpp"
#include "kiln/compiler/voxel_dag_builder.hpp"
#include "kiln/compiler/voxelizer.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/esvo.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/voxel_dag.hpp"
#include "kiln/tools/ray_generator.hpp"
#include "test_support.hpp"
#include "voxel_fixtures.hpp"

namespace kiln {
namespace {

using format::Double3;
using format::Float3;
using namespace kiln::test;

EsvoView view_of(const FlatEsvo& e) {
  return EsvoView(e.words, e.pages, e.blocks, e.normals, e.colors, frame_of(e.grid));
}

FlatEsvo build(const Scene& scene, std::uint32_t resolution, bool contours, unsigned threads = 2) {
  EsvoBuildOptions options;
  options.resolution = resolution;
  options.contours = contours;
  options.threads = threads;
  return build_esvo(scene, options);
}

// Primary rays at the mesh and random rays from inside the bounds.
std::vector<Ray> test_rays(const BvhView& bvh, const Scene& scene, std::size_t count,
                           std::uint32_t seed) {
  std::vector<Ray> rays =
      generate_rays({bvh, scene.positions, scene.triangles, scene.bounds.min, scene.bounds.max},
                    RayKind::kPrimary, count / 2, seed, 2);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(0, 1), sym(-1, 1);
  const Float3 lo = scene.bounds.min, hi = scene.bounds.max;
  while (rays.size() < count) {
    const Float3 o{lo.x + (hi.x - lo.x) * unit(rng), lo.y + (hi.y - lo.y) * unit(rng),
                   lo.z + (hi.z - lo.z) * unit(rng)};
    rays.push_back({o, 0.0f, {sym(rng), sym(rng), sym(rng)}, INFINITY});
  }
  return rays;
}

struct Fixture {
  Scene scene;
  FlatBvh flat;
  BvhView bvh() const { return BvhView(flat.nodes, flat.triangles, flat.prim_ids); }
};

Fixture load(const char* mesh) {
  Fixture f;
  f.scene = import_scene({mesh_path(mesh)}, 2);
  f.flat = build_bvh(f.scene, {});
  return f;
}

TEST(Esvo, WithoutContoursHitsAreTheDags) {
  KILN_REQUIRE_CORPUS();
  for (const auto& [mesh, resolution] : std::vector<std::pair<const char*, std::uint32_t>>{
           {"classic/teapot.obj", 64},
           {"classic/spot.obj", 128},
           {"stanford/stanford-bunny.obj.zst", 256}}) {
    const Fixture f = load(mesh);
    const BuiltDag dag = build_dag(f.scene, resolution);
    const FlatEsvo esvo = build(f.scene, resolution, false);
    EXPECT_EQ(esvo.leaf_count, dag.voxels.codes.size()) << mesh;
    EXPECT_EQ(esvo.contour_count, 0u);
    const VoxelDagView dag_view = dag.view();
    const EsvoView view = view_of(esvo);
    std::size_t hits = 0, hit_miss = 0, other_voxel = 0, other_t = 0, other_face = 0;
    for (const Ray& ray : test_rays(f.bvh(), f.scene, 10000, 7)) {
      const VoxelHit a = view.intersect(ray), b = dag_view.intersect(ray);
      if (a.hit() != b.hit()) {
        ++hit_miss;
        continue;
      }
      if (!a.hit()) continue;
      ++hits;
      // t is compared where it is well conditioned: as the distance moved across the entered
      // face (a grazing ray's t along the face is not), to a thousandth of a voxel.
      const float dir[3] = {ray.dir.x, ray.dir.y, ray.dir.z};
      float across = std::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
      for (int axis = 0; axis < 3; ++axis)
        if (b.face_normal[axis] != 0) across = std::fabs(dir[axis]);
      other_t += std::fabs(a.t - b.t) * across > 1e-3 * dag.voxels.grid.voxel_size;
      if (a.x != b.x || a.y != b.y || a.z != b.z) {
        ++other_voxel;
        continue;
      }
      other_face += std::memcmp(a.face_normal, b.face_normal, sizeof a.face_normal) != 0;
      EXPECT_EQ(std::memcmp(a.normal, b.normal, sizeof a.normal), 0);
    }
    EXPECT_GT(hits, 3000u) << mesh;
    EXPECT_EQ(hit_miss, 0u) << mesh;
    EXPECT_EQ(other_t, 0u) << mesh;
    // Two voxels that share the entry point (a ray through an edge or corner) are both right.
    EXPECT_LE(other_voxel, hits / 1000) << mesh;
    EXPECT_LE(other_face, hits / 1000) << mesh;
    std::cout << mesh << " " << resolution << "^3: " << hits << " hits, " << other_voxel
              << " on a neighbouring voxel at the same t, " << other_face << " other face\n";
  }
}

TEST(Esvo, ContourHitsLieWithinTheBoundAndBeatCubes) {
  KILN_REQUIRE_CORPUS();
  for (const auto& [mesh, resolution] : std::vector<std::pair<const char*, std::uint32_t>>{
           {"classic/spot.obj", 128},
           {"classic/fandisk.obj", 256},
           {"stanford/stanford-bunny.obj.zst", 256}}) {
    const Fixture f = load(mesh);
    const BvhView bvh = f.bvh();
    const FlatEsvo contoured = build(f.scene, resolution, true);
    const FlatEsvo cubes = build(f.scene, resolution, false);
    EsvoBuildOptions defaults;
    const double bound = esvo_error_bound(defaults) * contoured.grid.voxel_size;
    const EsvoView with = view_of(contoured), without = view_of(cubes);
    std::size_t rays_cast = 0, hits = 0, over = 0, wrong_with = 0, wrong_without = 0;
    double worst = 0, total = 0;
    for (const Ray& ray : test_rays(bvh, f.scene, 10000, 11)) {
      ++rays_cast;
      const bool mesh_hit = bvh.intersect(ray).prim != kNoHit;
      const VoxelHit a = with.intersect(ray);
      wrong_with += a.hit() != mesh_hit;
      wrong_without += without.intersect(ray).hit() != mesh_hit;
      if (!a.hit()) continue;
      ++hits;
      const Float3 p{ray.org.x + a.t * ray.dir.x, ray.org.y + a.t * ray.dir.y,
                     ray.org.z + a.t * ray.dir.z};
      const double distance = closest_point(bvh, p).distance;
      worst = std::max(worst, distance), total += distance;
      // Float rounding of the hit point: a millionth of the grid.
      over += distance > bound + 1e-6 * contoured.grid.voxel_size * resolution;
    }
    EXPECT_GT(hits, 3000u) << mesh;
    EXPECT_EQ(over, 0u) << mesh << ": worst " << worst / contoured.grid.voxel_size << " voxels";
    EXPECT_LT(wrong_with, wrong_without) << mesh;
    EXPECT_LT(contoured.descriptor_count, cubes.descriptor_count) << mesh;
    std::cout << mesh << " " << resolution << "^3: mean error "
              << total / double(hits) / contoured.grid.voxel_size << " voxels, worst "
              << worst / contoured.grid.voxel_size << " (bound " << esvo_error_bound(defaults)
              << "); hit/miss disagreement with the mesh " << wrong_with << " of " << rays_cast
              << " (cubes " << wrong_without << "); " << contoured.leaf_count << " leaves vs "
              << cubes.leaf_count << " cubes\n";
  }
}

std::vector<std::byte> esvo_blob(const Scene& scene, std::uint32_t resolution, bool contours,
                                 unsigned threads, bool compress = false) {
  return blob_with(scene,
                   "esvo:resolution=" + std::to_string(resolution) +
                       ",no-contours=" + (contours ? "false" : "true"),
                   threads, compress);
}

TEST(Esvo, BlobsAreByteIdenticalAndRoundTrip) {
  KILN_REQUIRE_CORPUS();
  const Fixture f = load("stanford/stanford-bunny.obj.zst");
  for (const bool contours : {true, false}) {
    const auto one = esvo_blob(f.scene, 256, contours, 1);
    EXPECT_EQ(one, esvo_blob(f.scene, 256, contours, 2));
    EXPECT_EQ(one, esvo_blob(f.scene, 256, contours, 3));
    EXPECT_EQ(one, esvo_blob(f.scene, 256, contours, 8));
    EXPECT_EQ(open_and_verify(one), "");
    EXPECT_EQ(open_and_verify(esvo_blob(f.scene, 256, contours, 2, true)), "");
    // The mapped blob answers as the builder's arrays do.
    const FlatEsvo flat = build(f.scene, 256, contours);
    const AlignedBuffer aligned = aligned_copy(one);
    const Blob blob = Blob::open_memory(aligned.bytes());
    const EsvoView mapped = EsvoView::from_blob(blob), direct = view_of(flat);
    EXPECT_EQ(mapped.counts().descriptors, flat.descriptor_count);
    for (const Ray& ray : test_rays(f.bvh(), f.scene, 2000, 3)) {
      const VoxelHit a = mapped.intersect(ray), b = direct.intersect(ray);
      ASSERT_EQ(std::memcmp(&a, &b, sizeof a), 0);
    }
  }
}

TEST(Esvo, CorruptedDescriptorsAreRefused) {
  KILN_REQUIRE_CORPUS();
  const Fixture f = load("classic/teapot.obj");
  const auto blob = esvo_blob(f.scene, 64, true, 2);
  const AlignedBuffer aligned = aligned_copy(blob);
  const Blob original = Blob::open_memory(aligned.bytes());
  const StructureInfo* esvo = original.structure("esvo");
  ASSERT_NE(esvo, nullptr);
  const auto* desc = &desc_of<schema::EsvoDesc>(original, *esvo);
  const auto words = original.section_view<std::uint32_t>(desc->words());
  auto expect_refused = [&](std::uint32_t section, std::size_t offset, std::uint32_t value,
                            const char* what) {
    const AlignedBuffer bad = forged_copy(blob, section, offset, value);
    const Blob b = Blob::open_memory(bad.bytes());  // open is O(sections)
    EXPECT_THROW(EsvoView::from_blob(b), BlobError) << what;
    EXPECT_THROW(b.verify(), BlobError) << what;
  };
  const std::uint32_t root = words[0];
  expect_refused(desc->words(), 0, (root & 0x1FFFF) | 0x7FFFu << 17, "child pointer past the end");
  expect_refused(desc->words(), 0, root & 0x1FFFF, "child pointer at itself");
  expect_refused(desc->words(), 0, root | 0x10000 | 0xFFFEu << 17, "far pointer past the end");
  expect_refused(desc->words(), 0, root & ~0xFF00u, "no valid children, non-leaf bits set");
  expect_refused(desc->words(), 4, 0xFFFFFFFFu, "contour pointer past the end");
  expect_refused(desc->pages(), 0, 7, "page header naming a missing block");
  expect_refused(desc->blocks(), 16, 1, "block starting inside block 0's first word");

  // Any single flipped bit in the descriptors: refused, or still a tree that casts safely
  // (under the sanitizers this also proves no read leaves the words).
  const auto rays = test_rays(f.bvh(), f.scene, 200, 9);
  std::size_t refused = 0, tried = 0;
  for (std::size_t word = 0; word < std::min<std::size_t>(words.size(), 400); word += 3)
    for (const int bit : {0, 9, 17, 20, 31}) {
      ++tried;
      const AlignedBuffer bad = forged_copy(blob, desc->words(), 4 * word, words[word] ^ 1u << bit);
      const Blob b = Blob::open_memory(bad.bytes());
      try {
        const EsvoView view = EsvoView::from_blob(b);
        for (const Ray& ray : rays) (void)view.intersect(ray);
      } catch (const BlobError&) {
        ++refused;
      }
    }
  EXPECT_GT(refused, tried / 4);
}

TEST(Esvo, OccupancyWithoutContoursIsTheVoxelSet) {
  KILN_REQUIRE_CORPUS();
  const Fixture f = load("classic/spot.obj");
  const BuiltDag dag = build_dag(f.scene, 32);
  const FlatEsvo esvo = build(f.scene, 32, false);
  const EsvoView view = view_of(esvo);
  const VoxelGrid& g = esvo.grid;
  for (std::uint32_t z = 0; z < 32; ++z)
    for (std::uint32_t y = 0; y < 32; ++y)
      for (std::uint32_t x = 0; x < 32; ++x) {
        const Float3 centre{float(g.origin[0] + (x + 0.5) * g.voxel_size),
                            float(g.origin[1] + (y + 0.5) * g.voxel_size),
                            float(g.origin[2] + (z + 0.5) * g.voxel_size)};
        const bool set = dag.view().occupied(x, y, z);
        ASSERT_EQ(view.occupied(centre), set) << x << " " << y << " " << z;
        ASSERT_EQ(dag.view().occupied(centre), set) << x << " " << y << " " << z;  // same grid
      }
}

TEST(Esvo, ContourLeavesHoldTheirHits) {
  KILN_REQUIRE_CORPUS();
  // A hit point lies on its leaf's region, so nudged a hundredth of a voxel along the ray it is
  // occupied (unless it was the region's far side, which a ray never enters through).
  const Fixture f = load("classic/fandisk.obj");
  const FlatEsvo esvo = build(f.scene, 128, true);
  const EsvoView view = view_of(esvo);
  std::size_t hits = 0, inside = 0;
  for (const Ray& ray : test_rays(f.bvh(), f.scene, 4000, 5)) {
    const VoxelHit h = view.intersect(ray);
    if (!h.hit()) continue;
    ++hits;
    const float length =
        std::sqrt(ray.dir.x * ray.dir.x + ray.dir.y * ray.dir.y + ray.dir.z * ray.dir.z);
    const float t = h.t + 0.01f * float(esvo.grid.voxel_size) / length;
    inside += view.occupied(
        {ray.org.x + t * ray.dir.x, ray.org.y + t * ray.dir.y, ray.org.z + t * ray.dir.z});
  }
  EXPECT_GT(hits, 1000u);
  EXPECT_GE(double(inside), 0.99 * double(hits));
}

TEST(Esvo, LevelOfDetailStopsEarlier) {
  KILN_REQUIRE_CORPUS();
  const Fixture f = load("stanford/stanford-bunny.obj.zst");
  const FlatEsvo esvo = build(f.scene, 256, true);
  const EsvoView view = view_of(esvo);
  // A cone 1024 voxels wide per unit of distance (the bunny is ~0.15 across): most rays stop
  // well above the leaves.
  const EsvoLod lod{float(esvo.grid.voxel_size * 1024), 0};
  std::size_t hits = 0, coarser = 0;
  for (const Ray& ray : test_rays(f.bvh(), f.scene, 2000, 13)) {
    const VoxelHit fine = view.intersect(ray), coarse = view.intersect(ray, lod);
    if (!fine.hit()) continue;
    ++hits;
    // The coarse voxel encloses the fine hit's region, so it is hit, no later.
    ASSERT_TRUE(coarse.hit());
    EXPECT_LE(coarse.t, fine.t + 1e-4f);
    EXPECT_LE(coarse.level, fine.level);
    coarser += coarse.level < fine.level;
  }
  EXPECT_GT(coarser, hits / 2);
}

TEST(Esvo, BadOptionsAreRefused) {
  KILN_REQUIRE_CORPUS();
  const Fixture f = load("classic/teapot.obj");
  EsvoBuildOptions options;
  options.resolution = 100;
  EXPECT_THROW(build_esvo(f.scene, options), std::invalid_argument);
  options.resolution = 64;
  options.contour_error = 1.5;
  EXPECT_THROW(build_esvo(f.scene, options), std::invalid_argument);
  options.contour_error = NAN;
  EXPECT_THROW(build_esvo(f.scene, options), std::invalid_argument);
  options.contour_error = std::sqrt(3.0);
  EXPECT_NEAR(esvo_error_bound(options), std::sqrt(3.0), 1e-12);
  options.contour_error = 3.4;
  EXPECT_NEAR(esvo_error_bound(options), std::sqrt(11.0), 1e-12);
}

TEST(Esvo, ColourAttachmentIsTheTouchingTrianglesMean) {
  KILN_REQUIRE_CORPUS();
  Fixture f = load("classic/spot.obj");
  // A colour per vertex from its position, so neighbouring triangles differ.
  for (const Float3& p : f.scene.positions) {
    const auto channel = [](float v) {
      return std::uint32_t(std::lround(127.5f + 127.5f * std::sin(9 * v)));
    };
    f.scene.colors.push_back(channel(p.x) | channel(p.y) << 8 | channel(p.z) << 16 | 0xFFu << 24);
  }
  const FlatEsvo esvo = build(f.scene, 64, true);
  ASSERT_EQ(esvo.colors.size(), esvo.normals.size());
  const EsvoView view = view_of(esvo);
  const VoxelGrid& g = esvo.grid;
  std::size_t hits = 0;
  for (const Ray& ray : test_rays(f.bvh(), f.scene, 1000, 17)) {
    const VoxelHit h = view.intersect(ray);
    if (!h.hit()) continue;
    ++hits;
    // The leaf's cube, then every triangle touching it, by brute force.
    const std::uint32_t side = g.resolution >> h.level;
    const Double3 lo{double(h.x / side * side), double(h.y / side * side),
                     double(h.z / side * side)};
    const Double3 hi{lo.x + side, lo.y + side, lo.z + side};
    double sum[4] = {0, 0, 0, 0};
    std::size_t count = 0;
    for (const auto& tri : f.scene.triangles) {
      const GridTriangle t = to_grid(g, f.scene.positions[tri.v[0]], f.scene.positions[tri.v[1]],
                                     f.scene.positions[tri.v[2]]);
      if (!triangle_overlaps_box(t.v[0], t.v[1], t.v[2], lo, hi)) continue;
      ++count;
      for (int k = 0; k < 4; ++k)
        for (const std::uint32_t v : tri.v)
          sum[k] += double(f.scene.colors[v] >> (8 * k) & 0xFF) / 3.0;
    }
    ASSERT_GT(count, 0u);
    for (int k = 0; k < 4; ++k)
      ASSERT_NEAR(double(h.color >> (8 * k) & 0xFF), sum[k] / double(count), 0.5 + 1e-9) << k;
  }
  EXPECT_GT(hits, 300u);
  // Without colours in the scene there is no colour attachment.
  f.scene.colors.clear();
  EXPECT_TRUE(build(f.scene, 64, true).colors.empty());
}

TEST(Esvo, CommandLineBuildDumpTrace) {
  KILN_REQUIRE_CORPUS();
  TempDir dir;
  const std::string mesh = mesh_path("classic/teapot.obj");
  const std::string blob = dir.file("e.kiln"), rays = dir.file("r.bin"), hits = dir.file("h.bin");
  ASSERT_EQ(run_kiln("build " + quoted(mesh) + " --accel esvo --resolution 128 -o " + quoted(blob))
                .exit_code,
            0);
  const auto dump = run_kiln("dump " + quoted(blob));
  EXPECT_NE(dump.out.find("bytes/leaf: hierarchy"), std::string::npos) << dump.out;
  const auto json = run_kiln("dump --json " + quoted(blob));
  EXPECT_NE(json.out.find("\"contour_bytes_per_leaf\""), std::string::npos) << json.out;
  EXPECT_EQ(run_kiln("verify " + quoted(blob)).exit_code, 0);
  ASSERT_EQ(run_kiln("rays " + quoted(mesh) + " --count 3000 -o " + quoted(rays)).exit_code, 0);
  ASSERT_EQ(run_kiln("trace " + quoted(blob) + " --accel esvo --rays " + quoted(rays) + " --out " +
                     quoted(hits))
                .exit_code,
            0);
  // The file holds what the library answers on the same blob and rays.
  const auto bytes = read_file(hits), ray_bytes = read_file(rays);
  ASSERT_EQ(bytes.size(), 3000 * sizeof(VoxelHitRecord));
  const AlignedBuffer aligned = aligned_copy(read_file(blob));
  const Blob opened = Blob::open_memory(aligned.bytes());
  const EsvoView view = EsvoView::from_blob(opened);
  std::size_t wrong = 0, hit_count = 0;
  for (std::size_t i = 0; i < 3000; ++i) {
    Ray ray;
    VoxelHitRecord from_file;
    std::memcpy(&ray, ray_bytes.data() + i * sizeof ray, sizeof ray);
    std::memcpy(&from_file, bytes.data() + i * sizeof from_file, sizeof from_file);
    const VoxelHit expected = view.intersect(ray);
    const VoxelHitRecord record = to_record(expected);
    wrong += std::memcmp(&from_file, &record, sizeof record) != 0;
    hit_count += expected.hit();
  }
  EXPECT_EQ(wrong, 0u);
  EXPECT_GT(hit_count, 300u);  // camera rays: about one in seven meets the teapot

  // kiln query --op occupied answers as EsvoView::occupied, on points near and away from hits.
  std::vector<Float3> points;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> jitter(-0.02f, 0.02f);
  for (std::size_t i = 0; i < 3000 && points.size() < 2000; ++i) {
    Ray ray;
    std::memcpy(&ray, ray_bytes.data() + i * sizeof ray, sizeof ray);
    const VoxelHit h = view.intersect(ray);
    if (!h.hit()) continue;
    const float t = h.t * (1.0f + jitter(rng));
    points.push_back(
        {ray.org.x + t * ray.dir.x, ray.org.y + t * ray.dir.y, ray.org.z + t * ray.dir.z});
  }
  write_file(dir.file("p.bin"), std::as_bytes(std::span<const Float3>(points)));
  ASSERT_EQ(run_kiln("query " + quoted(blob) + " --op occupied --in " + quoted(dir.file("p.bin")) +
                     " --out " + quoted(dir.file("o.bin")))
                .exit_code,
            0);
  const auto occupied = read_file(dir.file("o.bin"));
  ASSERT_EQ(occupied.size(), points.size());
  std::size_t inside = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    ASSERT_EQ(std::uint8_t(occupied[i]), view.occupied(points[i]) ? 1 : 0) << i;
    inside += std::uint8_t(occupied[i]);
  }
  EXPECT_GT(inside, points.size() / 10);
  EXPECT_LT(inside, points.size());
  for (const std::string bad : {"--resolution 100", "--resolution 4", "--contour-error 1",
                                "--contour-error nan", "--contour-error -3"}) {
    const auto result = run_kiln("build " + quoted(mesh) + " --accel esvo " + bad + " -o " +
                                 quoted(dir.file("x.kiln")));
    EXPECT_EQ(result.exit_code, 1) << bad;
    EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << result.err;
    EXPECT_FALSE(std::filesystem::exists(dir.file("x.kiln"))) << bad;
  }
}

}  // namespace
}  // namespace kiln
