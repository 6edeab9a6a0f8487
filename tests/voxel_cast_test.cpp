// Ray casts on the voxel DAG against a brute-force 3D-DDA (Amanatides & Woo 1987) over the same
// voxel set, occupancy lookups, the blob round trip and the command line.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/compiler/voxel_dag_builder.hpp"
#include "kiln/compiler/voxelizer.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/voxel_dag.hpp"
#include "kiln/tools/ray_generator.hpp"
#include "proximity_fixtures.hpp"
#include "test_support.hpp"
#include "voxel_fixtures.hpp"

namespace kiln {
namespace {

using format::Float3;
using namespace kiln::test;

// The reference: walk voxel by voxel in double, return the first set one.
VoxelHit dda(const BuiltDag& b, const Ray& ray) {
  const VoxelGrid& g = b.voxels.grid;
  const double n = g.resolution;
  const double org[3] = {ray.org.x, ray.org.y, ray.org.z};
  const double dir[3] = {ray.dir.x, ray.dir.y, ray.dir.z};
  double o[3], d[3];
  for (int a = 0; a < 3; ++a)
    o[a] = (org[a] - g.origin[a]) / g.voxel_size, d[a] = dir[a] / g.voxel_size;
  double t0 = ray.tmin, t1 = ray.tmax;
  int entry_axis = -1;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0) {
      if (o[a] < 0 || o[a] > n) return {};
      continue;
    }
    double lo = (0 - o[a]) / d[a], hi = (n - o[a]) / d[a];
    if (lo > hi) std::swap(lo, hi);
    if (lo > t0) t0 = lo, entry_axis = a;
    t1 = std::min(t1, hi);
  }
  if (t0 > t1) return {};
  std::int64_t v[3], step[3];
  double t_next[3], t_delta[3];
  for (int a = 0; a < 3; ++a) {
    const double p = o[a] + d[a] * t0;
    v[a] = std::clamp<std::int64_t>(std::int64_t(std::floor(p)), 0, g.resolution - 1);
    if (a == entry_axis) v[a] = d[a] > 0 ? 0 : g.resolution - 1;
    step[a] = d[a] > 0 ? 1 : -1;
    t_delta[a] = d[a] == 0 ? INFINITY : 1.0 / std::fabs(d[a]);
    t_next[a] = d[a] == 0 ? INFINITY : (double(v[a] + (d[a] > 0 ? 1 : 0)) - o[a]) / d[a];
  }
  double t_enter = t0;
  int axis = entry_axis;
  for (;;) {
    const std::uint64_t code =
        format::morton_code(std::uint32_t(v[0]), std::uint32_t(v[1]), std::uint32_t(v[2]));
    if (std::binary_search(b.voxels.codes.begin(), b.voxels.codes.end(), code)) {
      VoxelHit hit;
      hit.t = float(t_enter);
      hit.prim = 0;
      hit.x = std::uint32_t(v[0]), hit.y = std::uint32_t(v[1]), hit.z = std::uint32_t(v[2]);
      if (axis >= 0) hit.face_normal[axis] = d[axis] > 0 ? -1.0f : 1.0f;
      return hit;
    }
    int a = 0;
    for (int k = 1; k < 3; ++k)
      if (t_next[k] < t_next[a]) a = k;
    if (t_next[a] > t1) return {};
    t_enter = t_next[a];
    axis = a;
    v[a] += step[a];
    if (v[a] < 0 || v[a] >= std::int64_t(g.resolution)) return {};
    t_next[a] += t_delta[a];
  }
}

// Primary rays at the mesh and random rays from inside the bounds, some along the axes.
std::vector<Ray> test_rays(const Scene& scene, std::size_t count, std::uint32_t seed) {
  const FlatBvh flat = build_bvh(scene, {});
  const BvhView bvh(flat.nodes, flat.triangles, flat.prim_ids);
  std::vector<Ray> rays =
      generate_rays({bvh, scene.positions, scene.triangles, scene.bounds.min, scene.bounds.max},
                    RayKind::kPrimary, count / 2, seed, 2);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(0, 1), sym(-1, 1);
  const Float3 lo = scene.bounds.min, hi = scene.bounds.max;
  while (rays.size() < count) {
    const Float3 o{lo.x + (hi.x - lo.x) * unit(rng), lo.y + (hi.y - lo.y) * unit(rng),
                   lo.z + (hi.z - lo.z) * unit(rng)};
    Float3 d{sym(rng), sym(rng), sym(rng)};
    if (rays.size() % 10 == 0) {  // axis-aligned: zero direction components
      const int axis = int(rays.size() / 10 % 3);
      d = {axis == 0 ? 1.0f : 0.0f, axis == 1 ? -1.0f : 0.0f, axis == 2 ? 1.0f : 0.0f};
    }
    rays.push_back({o, 0.0f, d, INFINITY});
  }
  return rays;
}

TEST(VoxelCast, MatchesTheDdaOnCorpusMeshes) {
  KILN_REQUIRE_CORPUS();
  for (const auto& [mesh, resolution] :
       std::vector<std::pair<const char*, std::uint32_t>>{{"classic/teapot.obj", 64},
                                                          {"classic/spot.obj", 128},
                                                          {"stanford/stanford-bunny.obj.zst", 256},
                                                          {"classic/fandisk.obj", 512}}) {
    const Scene scene = import_scene({mesh_path(mesh)}, 2);
    const BuiltDag built = build_dag(scene, resolution);
    const VoxelDagView view = built.view();
    std::size_t hits = 0, wrong = 0, any_wrong = 0;
    for (const Ray& ray : test_rays(scene, 10000, 5)) {
      const VoxelHit a = view.intersect(ray), b = dda(built, ray);
      any_wrong += view.occluded(ray) != b.hit();
      if (a.hit() != b.hit()) {
        wrong += 1;
        continue;
      }
      if (!a.hit()) continue;
      hits += 1;
      const bool same = a.x == b.x && a.y == b.y && a.z == b.z &&
                        std::fabs(a.t - b.t) <= 1e-5f * std::max(1.0f, std::fabs(b.t)) &&
                        std::memcmp(a.face_normal, b.face_normal, sizeof a.face_normal) == 0;
      wrong += !same;
      // The attached normal is the voxel's own.
      float n[3];
      ASSERT_TRUE(view.attached_normal(a.x, a.y, a.z, n));
      EXPECT_EQ(std::memcmp(n, a.normal, sizeof n), 0);
    }
    EXPECT_GT(hits, 3000u) << mesh;
    EXPECT_EQ(wrong, 0u) << mesh << " at " << resolution;
    EXPECT_EQ(any_wrong, 0u) << mesh;
  }
}

TEST(VoxelCast, OccupancyMatchesTheVoxelSet) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({mesh_path("classic/spot.obj")}, 2);
  const BuiltDag built = build_dag(scene, 64);
  const VoxelDagView view = built.view();
  std::size_t set = 0;
  for (std::uint32_t z = 0; z < 64; ++z)
    for (std::uint32_t y = 0; y < 64; ++y)
      for (std::uint32_t x = 0; x < 64; ++x) {
        const bool expected = std::binary_search(
            built.voxels.codes.begin(), built.voxels.codes.end(), format::morton_code(x, y, z));
        ASSERT_EQ(view.occupied(x, y, z), expected) << x << " " << y << " " << z;
        set += expected;
      }
  EXPECT_EQ(set, built.voxels.codes.size());
  EXPECT_FALSE(view.occupied(64, 0, 0));
}

std::vector<std::byte> dag_blob(const Scene& scene, std::uint32_t resolution, bool normals,
                                unsigned threads, bool compress = false) {
  return blob_with(
      scene,
      "dag:resolution=" + std::to_string(resolution) + ",normals=" + (normals ? "true" : "false"),
      threads, compress);
}

TEST(VoxelCast, BlobsAreByteIdenticalAndRoundTrip) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({mesh_path("stanford/stanford-bunny.obj.zst")}, 2);
  const auto one = dag_blob(scene, 256, true, 1);
  EXPECT_EQ(one, dag_blob(scene, 256, true, 2));
  EXPECT_EQ(one, dag_blob(scene, 256, true, 8));
  const auto compressed = dag_blob(scene, 256, true, 2, true);
  EXPECT_EQ(open_and_verify(one), "");
  EXPECT_EQ(open_and_verify(compressed), "");
  const BuiltDag direct = build_dag(scene, 256);
  const auto rays = test_rays(scene, 2000, 9);
  for (const auto* bytes : {&one, &compressed}) {
    const AlignedBuffer aligned = aligned_copy(*bytes);
    const Blob blob = Blob::open_memory(aligned.bytes());
    const VoxelDagView view = VoxelDagView::from_blob(blob);
    for (const Ray& ray : rays) {
      const VoxelHit a = view.intersect(ray), b = direct.view().intersect(ray);
      ASSERT_EQ(std::memcmp(&a, &b, sizeof a), 0);
    }
  }
}

TEST(VoxelCast, CorruptedWordsAreRefused) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({mesh_path("classic/teapot.obj")}, 2);
  const auto blob = dag_blob(scene, 64, false, 2);
  const AlignedBuffer aligned = aligned_copy(blob);
  const Blob original = Blob::open_memory(aligned.bytes());
  const StructureInfo* dag = original.structure("dag");
  ASSERT_NE(dag, nullptr);
  const auto* desc = &desc_of<schema::VoxelDagDesc>(original, *dag);
  auto expect_refused = [&](std::size_t word, std::uint32_t value, const char* what) {
    const AlignedBuffer bad = forged_copy(blob, desc->words(), 4 * word, value);
    const Blob b = Blob::open_memory(bad.bytes());  // open is O(sections)
    EXPECT_THROW(VoxelDagView::from_blob(b), BlobError) << what;
    EXPECT_THROW(b.verify(), BlobError) << what;
  };
  expect_refused(0, 0x1FF, "mask wider than 8 bits");
  expect_refused(0, 0, "empty root");
  expect_refused(1, 0, "child pointing back at the root");
  expect_refused(1, 0xFFFFFF00u, "child out of range");
  expect_refused(1, std::uint32_t(desc->leaf_first_word() + 1), "pointer into a leaf's high word");
}

TEST(VoxelCast, CommandLineBuildDumpTrace) {
  KILN_REQUIRE_CORPUS();
  TempDir dir;
  const std::string blob = dir.file("d.kiln"), rays = dir.file("r.bin"), hits = dir.file("h.bin");
  ASSERT_EQ(run_kiln("build " + quoted(mesh_path("classic/teapot.obj")) +
                     " --accel dag --resolution 128 --voxel-normals -o " + quoted(blob))
                .exit_code,
            0);
  const auto dump = run_kiln("dump " + quoted(blob));
  EXPECT_NE(dump.out.find("4x4x4 leaf masks"), std::string::npos) << dump.out;
  const auto json = run_kiln("dump --json " + quoted(blob));
  EXPECT_NE(json.out.find("\"bits_per_voxel\""), std::string::npos);
  ASSERT_EQ(run_kiln("rays " + quoted(mesh_path("classic/teapot.obj")) + " --count 3000 -o " +
                     quoted(rays))
                .exit_code,
            0);
  ASSERT_EQ(run_kiln("trace " + quoted(blob) + " --accel dag --rays " + quoted(rays) + " --out " +
                     quoted(hits))
                .exit_code,
            0);
  const auto bytes = read_file(hits);
  ASSERT_EQ(bytes.size(), 3000 * sizeof(VoxelHitRecord));
  const Scene scene = import_scene({mesh_path("classic/teapot.obj")}, 2);
  const BuiltDag built = build_dag(scene, 128);
  const auto ray_bytes = read_file(rays);
  std::size_t wrong = 0;
  for (std::size_t i = 0; i < 3000; ++i) {
    Ray ray;
    VoxelHitRecord from_file;
    std::memcpy(&ray, ray_bytes.data() + i * sizeof ray, sizeof ray);
    std::memcpy(&from_file, bytes.data() + i * sizeof from_file, sizeof from_file);
    const VoxelHitRecord expected = to_record(built.view().intersect(ray));
    wrong += std::memcmp(&from_file, &expected, sizeof expected) != 0;
  }
  EXPECT_EQ(wrong, 0u);
  for (const char* bad : {"100", "0", "4", "262144"}) {
    const auto result =
        run_kiln("build " + quoted(mesh_path("classic/teapot.obj")) + " --accel dag --resolution " +
                 bad + " -o " + quoted(dir.file("x.kiln")));
    EXPECT_EQ(result.exit_code, 1) << bad;
    EXPECT_NE(result.err.find("power of two"), std::string::npos) << result.err;
    EXPECT_FALSE(std::filesystem::exists(dir.file("x.kiln")));
  }
}

// Solid voxelization: the surface plus exactly the voxels whose centre has winding number 1
// (brute force over every triangle), on closed meshes; voxels the surface already holds are
// excluded from the comparison (their centres may lie just outside).
TEST(VoxelSolid, InteriorMatchesTheWindingNumber) {
  KILN_REQUIRE_CORPUS();
  for (const auto& [mesh, resolution] : std::vector<std::pair<const char*, std::uint32_t>>{
           {"classic/spot.obj", 32}, {"classic/fandisk.obj", 16}, {"assimp/OBJ/box.obj", 16}}) {
    const Scene scene = import_scene({mesh_path(mesh)}, 2);
    const Voxels surface = voxelize_surface(scene, {resolution, false, 2});
    const VoxelLeaves solid = solid_leaves(scene, surface.grid, surface.codes, 2);
    const FlatVoxelDag dag = build_voxel_dag(solid, resolution);
    const auto codes = expand_voxel_dag(dag.words, dag.levels);
    EXPECT_EQ(codes.size(), solid.voxel_count);
    EXPECT_TRUE(
        std::includes(codes.begin(), codes.end(), surface.codes.begin(), surface.codes.end()));
    std::size_t inside = 0, wrong = 0;
    const VoxelGrid& g = surface.grid;
    for (std::uint32_t z = 0; z < resolution; ++z)
      for (std::uint32_t y = 0; y < resolution; ++y)
        for (std::uint32_t x = 0; x < resolution; ++x) {
          const std::uint64_t code = format::morton_code(x, y, z);
          if (std::binary_search(surface.codes.begin(), surface.codes.end(), code)) continue;
          const Float3 centre{float(g.origin[0] + (x + 0.5) * g.voxel_size),
                              float(g.origin[1] + (y + 0.5) * g.voxel_size),
                              float(g.origin[2] + (z + 0.5) * g.voxel_size)};
          const bool expected = std::lround(test::winding_number(scene, centre)) == 1;
          inside += expected;
          wrong += expected != std::binary_search(codes.begin(), codes.end(), code);
        }
    EXPECT_GT(inside, 0u) << mesh;
    EXPECT_EQ(wrong, 0u) << mesh;
  }
}

TEST(VoxelSolid, ByteIdenticalAcrossThreadCounts) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({mesh_path("classic/spot.obj")}, 2);
  BuildOptions options;
  options.inputs = {"spot"};
  // 256: two bricks per axis.
  options.structures.push_back(
      resolve_structure_request("dag:resolution=256,solid=true,normals=true", {}));
  options.threads = 1;
  const auto one = compile_blob(scene, options);
  options.threads = 3;
  EXPECT_EQ(one, compile_blob(scene, options));
  EXPECT_EQ(open_and_verify(one), "");
}

}  // namespace
}  // namespace kiln
