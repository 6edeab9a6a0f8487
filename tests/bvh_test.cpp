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
#include "kiln/runtime/watertight.hpp"
#include "kiln/tools/ray_generator.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

using format::Float3;

constexpr BvhBuilder kBuilders[] = {BvhBuilder::kBinned, BvhBuilder::kSweep, BvhBuilder::kSpatial};

float tri_t(const Scene& scene, std::uint32_t prim, const Ray& ray, float tmax) {
  const auto& t = scene.triangles[prim];
  float h, u, v;
  if (!intersect_watertight(prepare_watertight(ray), scene.positions[t.v[0]],
                            scene.positions[t.v[1]], scene.positions[t.v[2]], ray.tmin, tmax, h, u,
                            v))
    return INFINITY;
  return h;
}

Hit brute_force(const Scene& scene, const Ray& ray) {
  Hit best;
  float tmax = ray.tmax;
  const WatertightRay w = prepare_watertight(ray);
  for (std::uint32_t i = 0; i < scene.triangles.size(); ++i) {
    const auto& t = scene.triangles[i];
    float h, u, v;
    if (intersect_watertight(w, scene.positions[t.v[0]], scene.positions[t.v[1]],
                             scene.positions[t.v[2]], ray.tmin, tmax, h, u, v)) {
      tmax = h;
      best = {h, i, u, v};
    }
  }
  return best;
}

// Hit/miss equal, t within 1e-5 relative, primitive equal unless both are at exactly the same t.
void expect_agrees_with_brute_force(const Scene& scene, const BvhView& bvh,
                                    std::span<const Ray> rays) {
  std::size_t mismatches = 0;
  for (std::size_t i = 0; i < rays.size() && mismatches < 5; ++i) {
    const Hit expected = brute_force(scene, rays[i]);
    const Hit got = bvh.intersect(rays[i]);
    const bool ok_hit = (expected.prim == kNoHit) == (got.prim == kNoHit);
    bool ok = ok_hit;
    if (ok && got.prim != kNoHit) {
      ok = std::fabs(got.t - expected.t) <= 1e-5f * std::fabs(expected.t);
      if (got.prim != expected.prim)
        ok = ok && tri_t(scene, got.prim, rays[i], INFINITY) == expected.t;
    }
    const bool occluded = bvh.occluded(rays[i]);
    if (occluded != (expected.prim != kNoHit)) ok = false;
    if (!ok) {
      ++mismatches;
      ADD_FAILURE() << "ray " << i << ": brute force prim " << expected.prim << " t " << expected.t
                    << ", bvh prim " << got.prim << " t " << got.t << ", occluded " << occluded;
    }
  }
}

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

Scene make_scene(std::vector<Float3> positions, std::vector<format::Triangle> triangles) {
  Scene s;
  s.positions = std::move(positions);
  s.triangles = std::move(triangles);
  s.triangle_mesh.assign(s.triangles.size(), 0);
  s.meshes.push_back({"generated", 0, 0, s.triangles.size(), 0, s.positions.size()});
  s.sources.push_back({"generated", 0, 0});
  s.bounds = bounds_of(s.positions);
  s.input_triangle_count = s.triangles.size();
  return s;
}

Scene add_triangle(std::vector<Float3>& p, std::vector<format::Triangle>& t, Float3 a, Float3 b,
                   Float3 c) {
  const auto base = std::uint32_t(p.size());
  p.push_back(a), p.push_back(b), p.push_back(c);
  t.push_back({base, base + 1, base + 2});
  return {};
}

// Worst cases named in the issue, generated from a fixed seed.
std::map<std::string, Scene> worst_cases() {
  std::map<std::string, Scene> cases;
  std::mt19937 rng(1234);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  auto point = [&](float scale, float offset = 0) {
    return Float3{offset + scale * unit(rng), offset + scale * unit(rng),
                  offset + scale * unit(rng)};
  };
  {  // many large, mutually overlapping triangles
    std::vector<Float3> p;
    std::vector<format::Triangle> t;
    for (int i = 0; i < 1500; ++i) add_triangle(p, t, point(1), point(1), point(1));
    cases["overlapping"] = make_scene(p, t);
  }
  {  // needle-thin slivers
    std::vector<Float3> p;
    std::vector<format::Triangle> t;
    for (int i = 0; i < 1500; ++i) {
      const Float3 a = point(1), b = point(1);
      const Float3 c{0.5f * (a.x + b.x) + 1e-6f, 0.5f * (a.y + b.y), 0.5f * (a.z + b.z) + 1e-6f};
      add_triangle(p, t, a, b, c);
    }
    cases["slivers"] = make_scene(p, t);
  }
  {  // stacks of axis-parallel planes, each a grid of triangles
    std::vector<Float3> p;
    std::vector<format::Triangle> t;
    for (int axis = 0; axis < 3; ++axis)
      for (int layer = 0; layer < 4; ++layer)
        for (int i = 0; i < 8; ++i)
          for (int j = 0; j < 8; ++j) {
            auto at = [&](float u, float v) {
              const float w = 0.2f * float(layer) + 0.1f;
              return axis == 0 ? Float3{w, u, v} : axis == 1 ? Float3{u, w, v} : Float3{u, v, w};
            };
            const float u0 = i / 8.0f, u1 = (i + 1) / 8.0f, v0 = j / 8.0f, v1 = (j + 1) / 8.0f;
            add_triangle(p, t, at(u0, v0), at(u1, v0), at(u1, v1));
            add_triangle(p, t, at(u0, v0), at(u1, v1), at(u0, v1));
          }
    cases["axis_planes"] = make_scene(p, t);
  }
  {  // a huge triangle with a cluster of tiny ones: the teapot in a stadium
    std::vector<Float3> p;
    std::vector<format::Triangle> t;
    add_triangle(p, t, {-1e4f, -1e4f, -0.5f}, {1e4f, -1e4f, 0.5f}, {0, 1e4f, 0});
    for (int i = 0; i < 1500; ++i) {
      const Float3 c = point(0.01f);
      add_triangle(p, t, c, {c.x + 1e-3f, c.y, c.z}, {c.x, c.y + 1e-3f, c.z + 5e-4f});
    }
    cases["teapot_in_stadium"] = make_scene(p, t);
  }
  return cases;
}

// Rays from random points toward random points in the scene's box (plus axis-aligned ones,
// which exercise the slab test's infinities).
std::vector<Ray> box_rays(const Scene& s, std::size_t count) {
  std::mt19937 rng(99);
  std::uniform_real_distribution<float> unit(-0.2f, 1.2f);
  auto in_box = [&] {
    return Float3{s.bounds.min.x + (s.bounds.max.x - s.bounds.min.x) * unit(rng),
                  s.bounds.min.y + (s.bounds.max.y - s.bounds.min.y) * unit(rng),
                  s.bounds.min.z + (s.bounds.max.z - s.bounds.min.z) * unit(rng)};
  };
  std::vector<Ray> rays;
  for (std::size_t i = 0; i < count; ++i) {
    const Float3 o = in_box(), target = in_box();
    Float3 d{target.x - o.x, target.y - o.y, target.z - o.z};
    if (i % 4 == 0)
      d = i % 12 == 0 ? Float3{1, 0, 0} : i % 12 == 4 ? Float3{0, -1, 0} : Float3{0, 0, 1};
    rays.push_back({o, 0.0f, d, INFINITY});
  }
  return rays;
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

// An icosphere subdivided four times (5120 triangles, closed): rays from inside aimed exactly at
// every vertex and every edge midpoint must all hit.
Scene icosphere(int subdivisions) {
  const float g = (1.0f + std::sqrt(5.0f)) / 2.0f;
  std::vector<Float3> p = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0},
                           {0, -1, g}, {0, 1, g}, {0, -1, -g}, {0, 1, -g},
                           {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
  std::vector<format::Triangle> t = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                     {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                     {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                     {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  auto normalize = [](Float3 v) {
    const float l = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
    return Float3{v.x / l, v.y / l, v.z / l};
  };
  for (auto& v : p) v = normalize(v);
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> midpoint;
    auto mid = [&](std::uint32_t a, std::uint32_t b) {
      const auto key = std::minmax(a, b);
      if (const auto it = midpoint.find(key); it != midpoint.end()) return it->second;
      p.push_back(normalize({(p[a].x + p[b].x) / 2, (p[a].y + p[b].y) / 2, (p[a].z + p[b].z) / 2}));
      return midpoint[key] = std::uint32_t(p.size() - 1);
    };
    std::vector<format::Triangle> next;
    for (const auto& tri : t) {
      const auto a = mid(tri.v[0], tri.v[1]), b = mid(tri.v[1], tri.v[2]),
                 c = mid(tri.v[2], tri.v[0]);
      next.push_back({tri.v[0], a, c});
      next.push_back({tri.v[1], b, a});
      next.push_back({tri.v[2], c, b});
      next.push_back({a, b, c});
    }
    t = std::move(next);
  }
  return make_scene(p, t);
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
  options.accels.push_back({"bvh", {}, {}});
  BvhBuildOptions sbvh;
  sbvh.builder = BvhBuilder::kSpatial;
  options.accels.push_back({"sbvh", sbvh, {}});
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
  format::SectionEntry entry;
  std::memcpy(&entry, blob.data() + 64 + 64 * section, 64);
  std::memcpy(blob.data() + entry.offset + node_index * sizeof(node), &node, sizeof(node));
  entry.checksum =
      xxh3_64(std::span<const std::byte>(blob).subspan(entry.offset, entry.stored_size));
  std::memcpy(blob.data() + 64 + 64 * section, &entry, 64);
  format::FileHeader h;
  std::memcpy(&h, blob.data(), 64);
  h.section_table_checksum =
      xxh3_64(std::span<const std::byte>(blob).subspan(64, 64 * h.section_count));
  std::memcpy(blob.data(), &h, 64);
  h.header_checksum = xxh3_64(std::span<const std::byte>(blob).first(56));
  std::memcpy(blob.data(), &h, 64);
  return blob;
}

TEST(Bvh, CorruptedNodeArraysAreRefused) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({test::mesh_path("classic/teapot.obj")}, 2);
  const auto blob = blob_with_bvhs(scene, false, 2);
  AlignedBuffer aligned(blob.size(), 64);
  std::memcpy(aligned.data(), blob.data(), blob.size());
  const Blob original = Blob::open_memory(aligned.bytes());
  const auto* desc = original.manifest().accelerations()->Get(0)->bvh();
  const std::uint32_t section = desc->nodes();
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
    EXPECT_NE(std::string(e.what()).find("no acceleration structure 'sbvh'"), std::string::npos);
  }
}

}  // namespace
}  // namespace kiln
