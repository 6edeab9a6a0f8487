// BVH builders and traversal against brute force (every ray against every triangle, with the
// same watertight test), on corpus meshes and generated worst cases.
#include <cmath>
#include <cstring>
#include <map>
#include <random>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/formats/bvh.hpp"
#include "kiln/runtime/aligned_buffer.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/checksum.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/ray_structure.hpp"
#include "kiln/runtime/watertight.hpp"
#include "kiln/tools/ray_generator.hpp"
#include "ray_fixtures.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

using format::Float3;
using namespace kiln::test;

constexpr BvhBuilder kBuilders[] = {BvhBuilder::kBinned, BvhBuilder::kSweep, BvhBuilder::kSpatial};

FlatBvh build(const Scene& scene, BvhBuilder builder, unsigned threads = 2) {
  BvhBuildOptions o;
  o.builder = builder;
  o.threads = threads;
  return build_bvh(scene, o);
}

std::vector<Ray> corpus_rays(const Scene& scene, RayKind kind, std::size_t count) {
  const FlatBvh flat = build(scene, BvhBuilder::kBinned);
  const BvhView bvh(flat.nodes, flat.triangles, flat.prim_ids);
  return generate_rays({bvh, scene.positions, scene.triangles, scene.bounds.min, scene.bounds.max},
                       kind, count, 7, 2);
}

TEST(Bvh, AgreesWithBruteForceOnGeneratedWorstCases) {
  for (const auto& [name, scene] : worst_cases()) {
    SCOPED_TRACE(name);
    const auto rays = box_rays(scene, 600);
    for (const auto builder : kBuilders) {
      SCOPED_TRACE(bvh_builder_name(builder));
      const FlatBvh flat = build(scene, builder);
      expect_agrees_with_brute_force(scene, BvhView(flat.nodes, flat.triangles, flat.prim_ids),
                                     rays);
    }
  }
}

const char* kMeshes[] = {"classic/teapot.obj", "stanford/stanford-bunny.obj.zst",
                         "assimp/STL/Spider_binary.stl", "classic/fandisk.obj"};

TEST(Bvh, AgreesWithBruteForceOnCorpusMeshes) {
  KILN_REQUIRE_CORPUS();
  for (const char* mesh : kMeshes) {
    SCOPED_TRACE(mesh);
    const Scene scene = import_scene({test::mesh_path(mesh)}, 2);
    const std::size_t count = scene.triangles.size() > 20000 ? 150 : 400;
    for (const RayKind kind : {RayKind::kPrimary, RayKind::kDiffuse, RayKind::kShadow}) {
      const auto rays = corpus_rays(scene, kind, count);
      for (const auto builder : kBuilders) {
        SCOPED_TRACE(bvh_builder_name(builder));
        const FlatBvh flat = build(scene, builder);
        expect_agrees_with_brute_force(scene, BvhView(flat.nodes, flat.triangles, flat.prim_ids),
                                       rays);
      }
    }
  }
}

TEST(Bvh, WatertightThroughVerticesAndEdges) {
  const Scene sphere = icosphere(4);
  ASSERT_EQ(sphere.triangles.size(), 5120u);
  std::vector<Float3> targets = sphere.positions;
  for (const auto& t : sphere.triangles)
    for (int e = 0; e < 3; ++e) {
      const Float3 a = sphere.positions[t.v[e]], b = sphere.positions[t.v[(e + 1) % 3]];
      targets.push_back({(a.x + b.x) * 0.5f, (a.y + b.y) * 0.5f, (a.z + b.z) * 0.5f});
    }
  const Float3 origins[] = {{0, 0, 0}, {0.1f, -0.2f, 0.05f}, {-0.3f, 0.25f, 0.4f}};
  for (const auto builder : kBuilders) {
    SCOPED_TRACE(bvh_builder_name(builder));
    const FlatBvh flat = build(sphere, builder);
    const BvhView bvh(flat.nodes, flat.triangles, flat.prim_ids);
    std::size_t misses = 0, brute_misses = 0;
    for (const Float3& o : origins)
      for (const Float3& target : targets) {
        const Ray ray{o, 0.0f, {target.x - o.x, target.y - o.y, target.z - o.z}, INFINITY};
        misses += bvh.intersect(ray).prim == kNoHit;
        misses += !bvh.occluded(ray);
        // The triangle test itself, without the tree (one origin: brute force is slow).
        if (&o == &origins[0] && builder == BvhBuilder::kBinned)
          brute_misses += brute_force(sphere, ray).prim == kNoHit;
      }
    EXPECT_EQ(misses, 0u);
    EXPECT_EQ(brute_misses, 0u);
  }
}

TEST(Bvh, SahCostOrderSbvhSweepBinned) {
  KILN_REQUIRE_CORPUS();
  std::vector<std::pair<std::string, Scene>> scenes;
  for (const char* mesh : kMeshes)
    scenes.emplace_back(mesh, import_scene({test::mesh_path(mesh)}, 2));
  for (auto& [name, scene] : worst_cases()) scenes.emplace_back(name, std::move(scene));
  for (const auto& [name, scene] : scenes) {
    const double binned = build(scene, BvhBuilder::kBinned).stats.sah_cost;
    const double sweep = build(scene, BvhBuilder::kSweep).stats.sah_cost;
    const double sbvh = build(scene, BvhBuilder::kSpatial).stats.sah_cost;
    EXPECT_LE(sweep, binned * 1.01) << name;
    EXPECT_LE(sbvh, sweep * 1.01) << name;
    EXPECT_GT(sbvh, 0.0) << name;
  }
}

std::vector<std::byte> blob_with_bvhs(const Scene& scene, bool compress, unsigned threads) {
  BuildOptions options;
  options.inputs = {"generated"};
  options.threads = threads;
  options.compression.enabled = compress;
  options.structures = {resolve_structure_request("bvh:width=2", {}),
                        resolve_structure_request("sbvh:width=2", {})};
  return compile_blob(scene, options);
}

TEST(Bvh, BlobRoundTripGivesIdenticalHits) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({test::mesh_path("classic/teapot.obj")}, 2);
  const auto rays = corpus_rays(scene, RayKind::kDiffuse, 3000);
  test::TempDir dir;
  for (const bool compress : {false, true}) {
    const auto bytes = blob_with_bvhs(scene, compress, 2);
    EXPECT_EQ(bytes, blob_with_bvhs(scene, compress, 1)) << "thread count changed the blob";
    const std::string path = dir.file(compress ? "z.kiln" : "raw.kiln");
    test::write_file(path, bytes);
    const Blob from_file = Blob::open_file(path);
    EXPECT_NO_THROW(from_file.verify());
    AlignedBuffer aligned(bytes.size(), 64);
    std::memcpy(aligned.data(), bytes.data(), bytes.size());
    const Blob from_memory = Blob::open_memory(aligned.bytes());
    for (const char* name : {"bvh", "sbvh"}) {
      BvhBuildOptions o;
      o.builder = std::string(name) == "sbvh" ? BvhBuilder::kSpatial : BvhBuilder::kBinned;
      const FlatBvh flat = build_bvh(scene, o);
      const BvhView in_memory(flat.nodes, flat.triangles, flat.prim_ids);
      std::vector<Hit> expected(rays.size()), a(rays.size()), b(rays.size());
      trace_rays(in_memory, rays, expected, false, 1);
      trace_rays(BvhView::from_blob(from_file, name), rays, a, false, 2);
      trace_rays(BvhView::from_blob(from_memory, name), rays, b, false, 2);
      EXPECT_EQ(0, std::memcmp(expected.data(), a.data(), a.size() * sizeof(Hit))) << name;
      EXPECT_EQ(0, std::memcmp(expected.data(), b.data(), b.size() * sizeof(Hit))) << name;
    }
  }
}

// Rewrites one BVH node in a raw blob and fixes every checksum, as a forger would.
std::vector<std::byte> with_forged_node(std::vector<std::byte> blob, std::uint32_t section,
                                        std::uint32_t node_index, const format::BvhNode& node) {
  return with_patched_section(std::move(blob), section, node_index * sizeof(node),
                              std::as_bytes(std::span<const format::BvhNode>(&node, 1)));
}

TEST(Bvh, CorruptedNodeArraysAreRefused) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({test::mesh_path("classic/teapot.obj")}, 2);
  const auto blob = blob_with_bvhs(scene, false, 2);
  AlignedBuffer aligned(blob.size(), 64);
  std::memcpy(aligned.data(), blob.data(), blob.size());
  const Blob original = Blob::open_memory(aligned.bytes());
  const std::uint32_t section =
      desc_of<schema::BvhDesc>(original, original.structures()[0]).nodes();
  const auto nodes = original.section_view<format::BvhNode>(section);
  ASSERT_EQ(nodes[0].count, 0);

  auto expect_refused = [&](const format::BvhNode& forged, std::uint32_t index, const char* what) {
    const auto bad = with_forged_node(blob, section, index, forged);
    AlignedBuffer copy(bad.size(), 64);
    std::memcpy(copy.data(), bad.data(), bad.size());
    const Blob b = Blob::open_memory(copy.bytes());  // open is O(sections): it cannot see nodes
    EXPECT_THROW(BvhView::from_blob(b, "bvh"), BlobError) << what;
    EXPECT_THROW(b.verify(), BlobError) << what;
  };
  auto n = nodes[0];
  n.offset = 0xFFFFFF00u;
  expect_refused(n, 0, "child out of range");
  n = nodes[0];
  n.offset = 0;
  expect_refused(n, 0, "cycle to the root");
  n = nodes[0];
  n.axis = 7;
  expect_refused(n, 0, "bad axis");
  // A leaf whose range runs past the references.
  std::uint32_t leaf = 0;
  while (nodes[leaf].count == 0) ++leaf;
  n = nodes[leaf];
  n.count = 0xFFFF;
  expect_refused(n, leaf, "leaf range");

  // Bounds that no longer contain a child: only the deep check can see it.
  n = nodes[0];
  n.max[0] = n.min[0];
  const auto shrunk = with_forged_node(blob, section, 0, n);
  AlignedBuffer copy(shrunk.size(), 64);
  std::memcpy(copy.data(), shrunk.data(), shrunk.size());
  const Blob b = Blob::open_memory(copy.bytes());
  EXPECT_NO_THROW(BvhView::from_blob(b, "bvh"));
  EXPECT_THROW(b.verify(), BlobError);
}

TEST(Bvh, MissingStructureIsAClearError) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({test::mesh_path("assimp/OBJ/box.obj")}, 1);
  const auto bytes = compile_blob(scene, {});
  AlignedBuffer aligned(bytes.size(), 64);
  std::memcpy(aligned.data(), bytes.data(), bytes.size());
  const Blob blob = Blob::open_memory(aligned.bytes());
  try {
    BvhView::from_blob(blob, "sbvh");
    FAIL();
  } catch (const BlobError& e) {
    EXPECT_NE(std::string(e.what()).find("has no structure 'sbvh'"), std::string::npos);
  }
}

}  // namespace
}  // namespace kiln
