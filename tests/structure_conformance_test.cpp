// The conformance suites: every registered structure runs the same checks as the others of its
// capability, through the registries alone. Adding a structure to a suite is one line in
// kRayStructures, kPointStructures or kVoxelStructures below.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/compiler/structure_builder.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/bvh_wide.hpp"
#include "kiln/runtime/checksum.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "kiln/tools/inspect.hpp"
#include "ray_fixtures.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

// The structures each suite runs on: `kiln build --accel` specs. A ray structure's spec may end
// in "@KERNEL": the suite then runs with KILN_BVH_KERNEL=KERNEL (skipped where the CPU lacks it).
const char* const kRayStructures[] = {
    "bvh",
    "bvh:builder=sweep",
    "sbvh",
    "kdtree",
    "octree",
    "bvh:width=2",
    "sbvh:width=2",
    "bvh:width=4",
    "sbvh:width=4",
    "bvh:width=4@scalar",
    "bvh:width=4@sse",
    "bvh:width=4@avx2",
    "bvh:width=4@avx512",
    "sbvh@scalar",
    "sbvh@sse",
    "sbvh@avx2",
    "sbvh@avx512",
    "bvh:width=8",
    "sbvh:width=8@avx2",
    "bvh:boxes=u8",
    "sbvh:width=4,boxes=u8",
    "bvh:boxes=u8@scalar",
    "bvh:boxes=u8@sse",
    "bvh:width=4,boxes=u8@avx2",
    "bvh:boxes=u8@avx512",
    "bvh:presplit=evh",
    "bvh:presplit=evh,builder=sweep,width=2",
    "grid",
    "nested-grid",
};
const char* const kPointStructures[] = {
    "points",
    "points:split=median,leaf-size=3",
};
const char* const kVoxelStructures[] = {
    "dag:resolution=64",
    "dag:resolution=64,normals=true",
    "esvo:resolution=64,no-contours=true",
    "ssvdag:resolution=64",
};

// A blob kept alive with its (aligned) bytes, opened from memory.
struct OpenBlob {
  AlignedBuffer bytes;
  Blob blob;
  explicit OpenBlob(std::span<const std::byte> b)
      : bytes(test::aligned_copy(b)), blob(Blob::open_memory(bytes.bytes(), "test.kiln")) {}
  std::unique_ptr<StructureView> view() const {
    return open_structure(blob, blob.structures().front().name);
  }
};

// Records of `rays` through a structure's RayQueries.
std::vector<std::byte> records_of(const RayQueries& rays, std::span<const Ray> batch, bool any_hit,
                                  unsigned threads = 2) {
  std::vector<std::byte> out(batch.size() * rays.record_size());
  rays.trace_records(batch, out, any_hit, threads);
  return out;
}

std::vector<Ray> scene_rays(const Scene& scene, std::size_t count) {
  return test::box_rays(scene, count);
}

Scene teapot_or_icosphere() {
  if (test::corpus_present()) return import_scene({test::mesh_path("classic/teapot.obj")}, 2);
  return test::icosphere(3);
}

// ---------------------------------------------------------------------------------------------
// Ray structures over triangles.

class RayConformance : public testing::TestWithParam<const char*> {
 protected:
  void SetUp() override {
    const std::string param = GetParam();
    const auto at = param.find('@');
    spec_ = param.substr(0, at);
    if (at == std::string::npos) return;
    const std::string kernel = param.substr(at + 1);
    for (const BvhKernel k :
         {BvhKernel::kScalar, BvhKernel::kSse, BvhKernel::kAvx2, BvhKernel::kAvx512})
      if (kernel == bvh_kernel_name(k) && !bvh_kernel_supported(k))
        GTEST_SKIP() << "this CPU cannot run the " << kernel << " BVH kernel";
    setenv("KILN_BVH_KERNEL", kernel.c_str(), 1);
  }
  void TearDown() override { unsetenv("KILN_BVH_KERNEL"); }
  const std::string& spec() const { return spec_; }

 private:
  std::string spec_;
};

// Closest hits agree with brute force (hit/miss, t, prim unless tied); any-hit finds a hit
// exactly when closest-hit does, never nearer than the closest.
void expect_rays_agree(const Scene& scene, const RayQueries& rays, std::span<const Ray> batch) {
  ASSERT_EQ(rays.record_size(), sizeof(Hit));
  const auto closest = records_of(rays, batch, false);
  const auto any = records_of(rays, batch, true);
  std::size_t failures = 0;
  for (std::size_t i = 0; i < batch.size() && failures < 5; ++i) {
    Hit got, first;
    std::memcpy(&got, closest.data() + i * sizeof(Hit), sizeof(Hit));
    std::memcpy(&first, any.data() + i * sizeof(Hit), sizeof(Hit));
    const Hit expected = test::brute_force(scene, batch[i]);
    bool ok = expected.hit() == got.hit() && first.hit() == got.hit();
    if (ok && got.hit()) {
      ok = std::fabs(got.t - expected.t) <= 1e-5f * std::fabs(expected.t) && first.t >= got.t;
      if (got.prim != expected.prim)
        ok = ok && test::tri_t(scene, got.prim, batch[i], INFINITY) == expected.t;
    }
    ok = ok && rays.closest(batch[i]).prim == got.prim;
    if (!ok) {
      ++failures;
      ADD_FAILURE() << "ray " << i << ": brute force prim " << expected.prim << " t " << expected.t
                    << ", got prim " << got.prim << " t " << got.t << ", any-hit prim "
                    << first.prim;
    }
  }
}

TEST_P(RayConformance, AgreesWithBruteForceOnWorstCasesAndACorpusMesh) {
  std::map<std::string, Scene> scenes = test::worst_cases();
  scenes.emplace("mesh", teapot_or_icosphere());
  for (const auto& [name, scene] : scenes) {
    SCOPED_TRACE(name);
    const OpenBlob open(test::blob_with(scene, spec(), 2));
    const auto view = open.view();
    ASSERT_NE(view->rays(), nullptr);
    const auto batch = scene_rays(scene, 3000);
    expect_rays_agree(scene, *view->rays(), batch);
  }
}

// A closed icosphere shot through every vertex and edge midpoint from outside: no ray slips
// between triangles.
TEST_P(RayConformance, WatertightThroughVerticesAndEdges) {
  const Scene sphere = test::icosphere(2);
  const OpenBlob open(test::blob_with(sphere, spec(), 2));
  const auto view = open.view();
  std::vector<Ray> batch;
  auto aim = [&](format::Float3 p) {
    const format::Float3 org{p.x * 3 + 0.1f, p.y * 3 - 0.05f, p.z * 3 + 0.02f};
    batch.push_back({org, 0, {p.x - org.x, p.y - org.y, p.z - org.z}, INFINITY});
  };
  for (const auto& p : sphere.positions) aim(p);
  for (const auto& t : sphere.triangles)
    for (int e = 0; e < 3; ++e) {
      const auto& a = sphere.positions[t.v[e]];
      const auto& b = sphere.positions[t.v[(e + 1) % 3]];
      aim({(a.x + b.x) / 2, (a.y + b.y) / 2, (a.z + b.z) / 2});
    }
  const auto records = records_of(*view->rays(), batch, false);
  for (std::size_t i = 0; i < batch.size(); ++i) {
    Hit h;
    std::memcpy(&h, records.data() + i * sizeof(Hit), sizeof(Hit));
    EXPECT_TRUE(h.hit()) << "ray " << i << " slipped through";
  }
}

TEST_P(RayConformance, FileMemoryAndZstdRoundTripsTraceTheSame) {
  const Scene scene = teapot_or_icosphere();
  const auto raw = test::blob_with(scene, spec(), 2);
  const auto packed = test::blob_with(scene, spec(), 2, true);
  EXPECT_LT(packed.size(), raw.size());
  test::TempDir dir;
  test::write_file(dir.file("a.kiln"), raw);
  const Blob from_file = Blob::open_file(dir.file("a.kiln"));
  const OpenBlob from_memory(raw), from_zstd(packed);
  const auto batch = scene_rays(scene, 2000);
  const auto reference = records_of(*from_memory.view()->rays(), batch, false);
  const auto file_view = open_structure(from_file, from_file.structures().front().name);
  EXPECT_EQ(records_of(*file_view->rays(), batch, false), reference);
  EXPECT_EQ(records_of(*from_zstd.view()->rays(), batch, false), reference);
  EXPECT_EQ(records_of(*from_memory.view()->rays(), batch, false, 1), reference);
}

// Byte-identical blobs on 1, 2 and 8 threads, and between runs.
void expect_deterministic(const Scene& scene, const std::string& spec) {
  const auto one = test::blob_with(scene, spec, 1);
  EXPECT_EQ(one, test::blob_with(scene, spec, 1));
  EXPECT_EQ(one, test::blob_with(scene, spec, 2));
  EXPECT_EQ(one, test::blob_with(scene, spec, 8));
  EXPECT_EQ(test::open_and_verify(one), "");
}

TEST_P(RayConformance, ByteIdenticalAcrossThreadCounts) {
  expect_deterministic(teapot_or_icosphere(), spec());
}

// Random bytes written into each of the structure's sections, checksums recomputed so the
// corruption reaches the view: opening, viewing, tracing and verifying either refuse it with a
// BlobError or run safely (the sanitizer build checks "safely").
void expect_forgeries_refused_or_safe(const Scene& scene, const std::string& spec) {
  const auto blob = test::blob_with(scene, spec, 2);
  const OpenBlob clean(blob);
  const auto batch = scene_rays(scene, 64);
  std::mt19937 rng(11);
  for (const std::uint32_t section : clean.blob.structures().front().sections) {
    const auto& entry = clean.blob.sections()[section];
    for (int trial = 0; trial < 24 && entry.raw_size >= 4; ++trial) {
      const std::size_t offset = rng() % (entry.raw_size - 3);
      const std::uint32_t value = trial % 3 == 0   ? 0xFFFFFFFFu
                                  : trial % 3 == 1 ? rng()
                                                   : rng() % 64;
      const AlignedBuffer forged = test::forged_copy(blob, section, offset, value);
      try {
        const Blob b = Blob::open_memory(forged.bytes(), "forged.kiln");
        const auto view = open_structure(b, b.structures().front().name);
        if (view->rays() != nullptr) records_of(*view->rays(), batch, false);
        if (view->neighbors() != nullptr) {
          std::vector<Neighbor> out(4);
          view->neighbors()->nearest(batch[0].org, out);
        }
        if (view->occupancy() != nullptr) view->occupancy()->occupied(batch[0].org);
        b.verify();
      } catch (const BlobError& e) {
        EXPECT_NE(std::string(e.what()).find("forged.kiln"), std::string::npos) << e.what();
      }
    }
  }
}

TEST_P(RayConformance, ForgedAndFlippedBytesAreRefusedOrSafe) {
  expect_forgeries_refused_or_safe(test::icosphere(2), spec());
}

// kiln dump --json lists the structure with its name and kind; kiln verify passes.
void expect_dump_and_verify(const Scene& scene, const std::string& spec) {
  test::TempDir dir;
  const std::string path = dir.file("s.kiln");
  test::write_file(path, test::blob_with(scene, spec, 2));
  std::ostringstream out, err, human;
  ASSERT_EQ(run_dump(path, {true, false}, out, err), 0) << err.str();
  const auto json = nlohmann::json::parse(out.str());
  const StructureRequest request = resolve_structure_request(spec, {});
  const auto& structures = json["manifest"]["structures"];
  ASSERT_EQ(structures.size(), 1u);
  EXPECT_EQ(structures[0]["name"], request.name);
  EXPECT_EQ(structures[0]["kind"], request.kind);
  ASSERT_EQ(run_dump(path, {false, false}, human, err), 0);
  EXPECT_NE(human.str().find(request.kind), std::string::npos);
  std::ostringstream verify_out;
  EXPECT_EQ(run_verify(path, false, verify_out, err), 0) << err.str();
}

TEST_P(RayConformance, DumpAndVerify) {
  expect_dump_and_verify(test::icosphere(1), spec());
}

INSTANTIATE_TEST_SUITE_P(Registered, RayConformance, testing::ValuesIn(kRayStructures));

// ---------------------------------------------------------------------------------------------
// Point structures: k nearest and radius searches against a brute-force scan.

class PointConformance : public testing::TestWithParam<const char*> {};

std::vector<Neighbor> brute_force_neighbors(std::span<const format::Float3> points,
                                            const format::Float3& q) {
  std::vector<Neighbor> all;
  for (std::uint32_t i = 0; i < points.size(); ++i) {
    const float dx = points[i].x - q.x, dy = points[i].y - q.y, dz = points[i].z - q.z;
    all.push_back({i, (dx * dx + dy * dy) + dz * dz});
  }
  std::sort(all.begin(), all.end(), closer);
  return all;
}

void expect_neighbors_agree(const Scene& scene, const NeighborQueries& points) {
  const auto queries = scene_rays(scene, 200);
  for (const Ray& r : queries) {
    const auto expected = brute_force_neighbors(scene.positions, r.org);
    std::vector<Neighbor> got(8);
    got.resize(points.nearest(r.org, got));
    ASSERT_EQ(got.size(), std::min<std::size_t>(8, expected.size()));
    for (std::size_t i = 0; i < got.size(); ++i) {
      EXPECT_EQ(got[i].id, expected[i].id);
      EXPECT_EQ(got[i].distance2, expected[i].distance2);
    }
    const float radius =
        std::sqrt(expected[std::min<std::size_t>(20, expected.size() - 1)].distance2);
    std::vector<Neighbor> within;
    points.within_radius(r.org, radius, within);
    std::size_t count = 0;
    while (count < expected.size() && expected[count].distance2 <= radius * radius) ++count;
    ASSERT_EQ(within.size(), count);
    for (std::size_t i = 0; i < count; ++i) EXPECT_EQ(within[i].id, expected[i].id);
  }
}

TEST_P(PointConformance, AgreesWithBruteForce) {
  for (const Scene& scene : {teapot_or_icosphere(), test::worst_cases().begin()->second}) {
    const OpenBlob open(test::blob_with(scene, GetParam(), 2));
    const auto view = open.view();
    ASSERT_NE(view->neighbors(), nullptr);
    EXPECT_EQ(view->rays(), nullptr);
    expect_neighbors_agree(scene, *view->neighbors());
  }
}

TEST_P(PointConformance, ByteIdenticalAcrossThreadCounts) {
  expect_deterministic(teapot_or_icosphere(), GetParam());
}

TEST_P(PointConformance, ForgedAndFlippedBytesAreRefusedOrSafe) {
  expect_forgeries_refused_or_safe(test::icosphere(2), GetParam());
}

TEST_P(PointConformance, DumpAndVerify) {
  expect_dump_and_verify(test::icosphere(1), GetParam());
}

INSTANTIATE_TEST_SUITE_P(Registered, PointConformance, testing::ValuesIn(kPointStructures));

// ---------------------------------------------------------------------------------------------
// Voxel structures: every hit lies on an occupied voxel the ray enters, any-hit agrees with
// closest-hit, and all voxel structures of one grid agree with each other (the same cubes).

class VoxelConformance : public testing::TestWithParam<const char*> {};

std::vector<VoxelHitRecord> voxel_records(const RayQueries& rays, std::span<const Ray> batch,
                                          bool any_hit) {
  EXPECT_EQ(rays.record_size(), sizeof(VoxelHitRecord));
  const auto bytes = records_of(rays, batch, any_hit);
  std::vector<VoxelHitRecord> out(batch.size());
  std::memcpy(out.data(), bytes.data(), bytes.size());
  return out;
}

TEST_P(VoxelConformance, HitsAreOccupiedAndAnyHitAgrees) {
  const Scene scene = teapot_or_icosphere();
  const OpenBlob open(test::blob_with(scene, GetParam(), 2));
  const auto view = open.view();
  ASSERT_NE(view->rays(), nullptr);
  ASSERT_NE(view->occupancy(), nullptr);
  const auto batch = scene_rays(scene, 3000);
  const auto closest = voxel_records(*view->rays(), batch, false);
  const auto any = voxel_records(*view->rays(), batch, true);
  std::size_t hits = 0, off_voxel = 0;
  for (std::size_t i = 0; i < batch.size(); ++i) {
    EXPECT_EQ(closest[i].x != kNoHit, any[i].x != kNoHit) << "ray " << i;
    if (closest[i].x == kNoHit) continue;
    ++hits;
    // A little past the entry point the ray is inside the hit voxel's solid.
    const Ray& r = batch[i];
    const float t = closest[i].t * (1 + 1e-4f) + 1e-4f;
    const format::Float3 p{r.org.x + r.dir.x * t, r.org.y + r.dir.y * t, r.org.z + r.dir.z * t};
    off_voxel += !view->occupancy()->occupied(p);
  }
  EXPECT_GT(hits, batch.size() / 10);
  EXPECT_LE(off_voxel, hits / 100) << "hits whose entry point is not occupied";
}

// Every voxel structure on one grid hits the same voxels as the first one listed (the cubes are
// the same set, whatever the layout).
TEST_P(VoxelConformance, AgreesWithTheOtherVoxelStructures) {
  const Scene scene = teapot_or_icosphere();
  const auto batch = scene_rays(scene, 3000);
  const OpenBlob reference(test::blob_with(scene, kVoxelStructures[0], 2));
  const OpenBlob open(test::blob_with(scene, GetParam(), 2));
  const auto expected = voxel_records(*reference.view()->rays(), batch, false);
  const auto got = voxel_records(*open.view()->rays(), batch, false);
  for (std::size_t i = 0; i < batch.size(); ++i) {
    ASSERT_EQ(got[i].x, expected[i].x) << "ray " << i;
    ASSERT_EQ(got[i].y, expected[i].y);
    ASSERT_EQ(got[i].z, expected[i].z);
    // The same entry face; t from each layout's own arithmetic.
    if (expected[i].x == kNoHit) continue;
    ASSERT_NEAR(got[i].t, expected[i].t, 1e-5f * std::max(1.0f, std::fabs(expected[i].t)));
  }
}

TEST_P(VoxelConformance, ZstdRoundTripTracesTheSame) {
  const Scene scene = teapot_or_icosphere();
  const OpenBlob raw(test::blob_with(scene, GetParam(), 2)),
      packed(test::blob_with(scene, GetParam(), 2, true));
  const auto batch = scene_rays(scene, 2000);
  const auto a = records_of(*raw.view()->rays(), batch, false);
  EXPECT_EQ(records_of(*packed.view()->rays(), batch, false), a);
  EXPECT_EQ(records_of(*raw.view()->rays(), batch, false, 1), a);
}

TEST_P(VoxelConformance, ByteIdenticalAcrossThreadCounts) {
  expect_deterministic(teapot_or_icosphere(), GetParam());
}

TEST_P(VoxelConformance, ForgedAndFlippedBytesAreRefusedOrSafe) {
  expect_forgeries_refused_or_safe(test::icosphere(2), GetParam());
}

TEST_P(VoxelConformance, DumpAndVerify) {
  expect_dump_and_verify(test::icosphere(1), GetParam());
}

INSTANTIATE_TEST_SUITE_P(Registered, VoxelConformance, testing::ValuesIn(kVoxelStructures));

// ---------------------------------------------------------------------------------------------
// The registries agree: every builder's kind is known to the runtime, consuming the same input.

TEST(Registry, EveryBuilderKindIsARuntimeKind) {
  ASSERT_FALSE(structure_builders().empty());
  for (const StructureBuilder* builder : structure_builders()) {
    const StructureKind* kind = find_structure_kind(builder->kind);
    ASSERT_NE(kind, nullptr) << builder->kind;
    EXPECT_EQ(kind->consumes, builder->consumes) << builder->kind;
  }
  EXPECT_EQ(structure_kinds().size(), structure_builders().size());
}

// Two structures of one kind under different names, each opened by its name.
TEST(Registry, StructuresAreNamedApartFromTheirKind) {
  const Scene scene = test::icosphere(2);
  BuildOptions options;
  options.inputs = {"generated"};
  options.structures = {resolve_structure_request("bvh:name=coarse,max-leaf=16", {}),
                        resolve_structure_request("bvh:name=fine,max-leaf=1", {})};
  const OpenBlob open(compile_blob(scene, options));
  ASSERT_EQ(open.blob.structures().size(), 2u);
  EXPECT_EQ(open.blob.structures()[0].name, "coarse");
  EXPECT_EQ(open.blob.structures()[1].kind, "bvh");
  const auto batch = scene_rays(scene, 500);
  EXPECT_EQ(records_of(*open_structure(open.blob, "coarse")->rays(), batch, false),
            records_of(*open_structure(open.blob, "fine")->rays(), batch, false));
  EXPECT_THROW(open_structure(open.blob, "missing"), BlobError);
  options.structures.push_back(resolve_structure_request("kdtree:name=fine", {}));
  EXPECT_THROW(compile_blob(scene, options), std::exception);
}

// A format 1.x blob is refused with the message to rebuild it.
TEST(Registry, FormatOneBlobsAskForARebuild) {
  auto blob = test::blob_with(test::icosphere(1), "bvh", 1);
  format::FileHeader h;
  std::memcpy(&h, blob.data(), sizeof h);
  h.version_major = 1;
  h.header_checksum = 0;
  std::memcpy(blob.data(), &h, sizeof h);
  h.header_checksum = xxh3_64(std::span<const std::byte>(blob).first(56));
  std::memcpy(blob.data(), &h, sizeof h);
  const std::string error = test::open_only(blob);
  EXPECT_NE(error.find("rebuild"), std::string::npos) << error;
  EXPECT_NE(error.find("kiln build"), std::string::npos) << error;
}

}  // namespace
}  // namespace kiln
