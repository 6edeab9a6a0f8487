// The SAH k-d tree against brute force and against the BVH, on corpus meshes and generated
// worst cases; its layout checks, determinism and command line.
#include <cmath>
#include <cstring>
#include <random>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/compiler/kdtree_builder.hpp"
#include "kiln/runtime/aligned_buffer.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/kdtree.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/ray_structure.hpp"
#include "kiln/tools/ray_generator.hpp"
#include "ray_fixtures.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

using format::Float3;
using namespace kiln::test;

struct BuiltKdTree {
  FlatKdTree flat;
  KdTreeView view() const {
    return KdTreeView(flat.nodes, flat.prim_ids, flat.triangles, flat.bounds);
  }
};

BuiltKdTree build(const Scene& scene, unsigned threads = 2) {
  KdTreeBuildOptions o;
  o.threads = threads;
  return {build_kdtree(scene, o)};
}

std::vector<Ray> corpus_rays(const Scene& scene, RayKind kind, std::size_t count) {
  const FlatBvh flat = build_bvh(scene, {});
  const BvhView bvh(flat.nodes, flat.triangles, flat.prim_ids);
  return generate_rays({bvh, scene.positions, scene.triangles, scene.bounds.min, scene.bounds.max},
                       kind, count, 11, 2);
}

TEST(KdTree, AgreesWithBruteForceOnGeneratedWorstCases) {
  for (const auto& [name, scene] : worst_cases()) {
    SCOPED_TRACE(name);
    const BuiltKdTree tree = build(scene);
    expect_agrees_with_brute_force(scene, tree.view(), box_rays(scene, 600));
  }
}

TEST(KdTree, AgreesWithBruteForceOnCorpusMeshes) {
  KILN_REQUIRE_CORPUS();
  for (const char* mesh : {"classic/teapot.obj", "stanford/stanford-bunny.obj.zst",
                           "assimp/STL/Spider_binary.stl", "classic/fandisk.obj"}) {
    SCOPED_TRACE(mesh);
    const Scene scene = import_scene({test::mesh_path(mesh)}, 2);
    const BuiltKdTree tree = build(scene);
    const std::size_t count = scene.triangles.size() > 20000 ? 150 : 400;
    for (const RayKind kind : {RayKind::kPrimary, RayKind::kDiffuse, RayKind::kShadow})
      expect_agrees_with_brute_force(scene, tree.view(), corpus_rays(scene, kind, count));
  }
}

// Many more rays than brute force can afford: against the BVH, with the same rules.
TEST(KdTree, AgreesWithTheBvhOnManyRays) {
  KILN_REQUIRE_CORPUS();
  for (const char* mesh : {"stanford/stanford-bunny.obj.zst",
                           "gltf/2CylinderEngine-glTF-Binary/2CylinderEngine.glb"}) {
    SCOPED_TRACE(mesh);
    const Scene scene = import_scene({test::mesh_path(mesh)}, 2);
    const BuiltKdTree tree = build(scene);
    BvhBuildOptions sbvh;
    sbvh.builder = BvhBuilder::kSpatial;
    const FlatBvh flat = build_bvh(scene, sbvh);
    const BvhView bvh(flat.nodes, flat.triangles, flat.prim_ids);
    for (const RayKind kind : {RayKind::kPrimary, RayKind::kDiffuse, RayKind::kShadow}) {
      const auto rays = corpus_rays(scene, kind, 10000);
      std::vector<Hit> expected(rays.size()), got(rays.size()), any(rays.size());
      trace_rays(bvh, rays, expected, false, 2);
      trace_rays(tree.view(), rays, got, false, 2);
      trace_rays(tree.view(), rays, any, true, 2);
      std::size_t failures = 0, hits = 0;
      for (std::size_t i = 0; i < rays.size() && failures < 5; ++i) {
        const Hit& e = expected[i];
        const Hit& g = got[i];
        hits += e.prim != kNoHit;
        bool ok = (e.prim == kNoHit) == (g.prim == kNoHit) &&
                  (e.prim == kNoHit) == (any[i].prim == kNoHit);
        if (ok && e.prim != kNoHit) {
          ok = std::fabs(g.t - e.t) <= 1e-5f * std::fabs(e.t);
          if (g.prim != e.prim) ok = ok && tri_t(scene, g.prim, rays[i], INFINITY) == e.t;
        }
        if (!ok) {
          ++failures;
          ADD_FAILURE() << "ray " << i << ": bvh prim " << e.prim << " t " << e.t
                        << ", kdtree prim " << g.prim << " t " << g.t;
        }
      }
      EXPECT_GT(hits, rays.size() / 20);  // the rays do reach the surface
    }
  }
}

TEST(KdTree, WatertightThroughVerticesAndEdges) {
  const Scene sphere = icosphere(4);
  std::vector<Float3> targets = sphere.positions;
  for (const auto& t : sphere.triangles)
    for (int e = 0; e < 3; ++e) {
      const Float3 a = sphere.positions[t.v[e]], b = sphere.positions[t.v[(e + 1) % 3]];
      targets.push_back({(a.x + b.x) * 0.5f, (a.y + b.y) * 0.5f, (a.z + b.z) * 0.5f});
    }
  const BuiltKdTree tree = build(sphere);
  const KdTreeView view = tree.view();
  std::size_t misses = 0;
  for (const Float3& o : {Float3{0, 0, 0}, Float3{0.1f, -0.2f, 0.05f}, Float3{-0.3f, 0.25f, 0.4f}})
    for (const Float3& target : targets) {
      const Ray ray{o, 0.0f, {target.x - o.x, target.y - o.y, target.z - o.z}, INFINITY};
      misses += view.intersect(ray).prim == kNoHit;
      misses += !view.occluded(ray);
    }
  EXPECT_EQ(misses, 0u);
}

// Rays running inside split planes and along axes, where plane distances are 0 x inf.
TEST(KdTree, RaysInsideSplitPlanesAndParallelToThem) {
  const auto cases = worst_cases();
  const Scene& scene = cases.at("axis_planes");
  const BuiltKdTree tree = build(scene);
  const KdTreeView view = tree.view();
  std::vector<Ray> rays;
  for (const auto& n : tree.flat.nodes) {
    if (n.is_leaf() || rays.size() > 3000) continue;
    Float3 o{0.37f, 0.41f, 0.53f};
    (&o.x)[n.axis()] = n.split();
    for (const Float3 d : {Float3{1, 0, 0}, Float3{0, -1, 0}, Float3{0, 0, 1}, Float3{1, 1, 0},
                           Float3{0, 1, -1}, Float3{-1, 0, 1}}) {
      rays.push_back({o, 0.0f, d, INFINITY});
      rays.push_back({{o.x - 2 * d.x, o.y - 2 * d.y, o.z - 2 * d.z}, 0.0f, d, INFINITY});
    }
  }
  ASSERT_GT(rays.size(), 100u);
  expect_agrees_with_brute_force(scene, view, rays);
}

TEST(KdTree, EveryTriangleIsReferencedAndTheDepthIsCapped) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({test::mesh_path("classic/teapot.obj")}, 2);
  const BuiltKdTree tree = build(scene);
  const KdTreeStatistics& s = tree.flat.stats;
  std::vector<bool> seen(scene.triangles.size());
  for (const auto id : tree.flat.prim_ids) seen[id] = true;
  EXPECT_EQ(std::count(seen.begin(), seen.end(), false), 0);
  EXPECT_LE(s.max_depth, s.depth_limit);
  EXPECT_EQ(s.depth_limit, kd_depth_limit(scene.triangles.size()));
  EXPECT_EQ(s.node_count, 2 * s.leaf_count - 1);
  EXPECT_GE(s.references_per_triangle, 1.0);
  // The SAH chose to split: the tree must be cheaper than one leaf holding everything.
  EXPECT_LT(s.sah_cost, 20.0 * double(scene.triangles.size()));
  EXPECT_GT(s.sah_cost, 0.0);
}

// Perfect splits: the clipped box holds every point of the triangle inside the cell and nothing
// outside the cell; a triangle missing the cell gives an empty box.
TEST(KdTree, ClippedTriangleBoundsAreTight) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> unit(-1.0f, 2.0f), w(0.0f, 1.0f);
  const format::Box3f cell{{0, 0, 0}, {1, 0.5f, 1}};
  int empty = 0;
  for (int i = 0; i < 2000; ++i) {
    const Float3 a{unit(rng), unit(rng), unit(rng)}, b{unit(rng), unit(rng), unit(rng)},
        c{unit(rng), unit(rng), unit(rng)};
    const format::Box3f box = clip_triangle_to_box(a, b, c, cell);
    empty += box.empty();
    for (int k = 0; k < 3 && !box.empty(); ++k) {
      EXPECT_GE(format::at(box.min, k), format::at(cell.min, k));
      EXPECT_LE(format::at(box.max, k), format::at(cell.max, k));
    }
    for (int s = 0; s < 200; ++s) {
      float u = w(rng), v = w(rng);
      if (u + v > 1) u = 1 - u, v = 1 - v;
      const Float3 p{a.x + u * (b.x - a.x) + v * (c.x - a.x),
                     a.y + u * (b.y - a.y) + v * (c.y - a.y),
                     a.z + u * (b.z - a.z) + v * (c.z - a.z)};
      const float q[3] = {p.x, p.y, p.z};
      bool inside_cell = true;
      for (int k = 0; k < 3; ++k)
        inside_cell =
            inside_cell && q[k] > format::at(cell.min, k) && q[k] < format::at(cell.max, k);
      if (!inside_cell) continue;
      ASSERT_FALSE(box.empty()) << "triangle " << i << " has a point inside the cell";
      for (int k = 0; k < 3; ++k) {
        EXPECT_GE(q[k], format::at(box.min, k) - 1e-6f);
        EXPECT_LE(q[k], format::at(box.max, k) + 1e-6f);
      }
    }
  }
  EXPECT_GT(empty, 0);  // some random triangles miss the cell
  // A triangle whose box overlaps the cell while the triangle itself does not.
  EXPECT_TRUE(
      clip_triangle_to_box({3.0f, -1.0f, 0.5f}, {3.0f, 3.0f, 0.5f}, {-1.0f, 3.0f, 0.5f}, cell)
          .empty());
}

std::vector<std::byte> kdtree_blob(const Scene& scene, unsigned threads) {
  BuildOptions options;
  options.inputs = {"generated"};
  options.threads = threads;
  options.structures = {resolve_structure_request("kdtree", {})};
  return compile_blob(scene, options);
}

TEST(KdTree, BuildsAreByteIdenticalAcrossThreadCounts) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({test::mesh_path("stanford/stanford-bunny.obj.zst")}, 2);
  const auto one = kdtree_blob(scene, 1);
  EXPECT_EQ(one, kdtree_blob(scene, 2));
  EXPECT_EQ(one, kdtree_blob(scene, 8));
  EXPECT_EQ(test::open_and_verify(one), "");
}

TEST(KdTree, CorruptedNodeArraysAreRefused) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({test::mesh_path("classic/teapot.obj")}, 2);
  const auto blob = kdtree_blob(scene, 2);
  const AlignedBuffer aligned = aligned_copy(blob);
  const Blob original = Blob::open_memory(aligned.bytes());
  ASSERT_EQ(original.structures()[0].kind, "kdtree");
  const auto* desc = &desc_of<schema::KdTreeDesc>(original, original.structures()[0]);
  const auto nodes = original.section_view<format::KdNode>(desc->nodes());
  ASSERT_FALSE(nodes[0].is_leaf());
  std::uint32_t leaf = 0;
  while (!nodes[leaf].is_leaf()) ++leaf;

  auto forge = [&](std::uint32_t section, std::size_t offset, const auto& value) {
    return forged_copy(blob, section, offset, value);
  };
  auto expect_refused = [&](const AlignedBuffer& copy, const char* what) {
    const Blob b = Blob::open_memory(copy.bytes());  // open is O(sections): it cannot see nodes
    EXPECT_THROW(KdTreeView::from_blob(b, "kdtree"), BlobError) << what;
    EXPECT_THROW(b.verify(), BlobError) << what;
  };
  const auto root = nodes[0];
  expect_refused(forge(desc->nodes(), 0, format::KdNode::interior(0, root.split(), 0x3FFFFF00u)),
                 "child out of range");
  expect_refused(forge(desc->nodes(), 0, format::KdNode::interior(1, root.split(), 0)),
                 "cycle to the root");
  expect_refused(forge(desc->nodes(), leaf * sizeof(format::KdNode),
                       format::KdNode::leaf(nodes[leaf].first_reference(), 0x3FFFFFFFu)),
                 "leaf range");
  expect_refused(forge(desc->prim_ids(), 0, std::uint32_t{0xFFFFFF00u}), "primitive id");
  // A split outside its cell keeps the layout valid: only the deep check sees it.
  const auto moved = forge(desc->nodes(), 0,
                           format::KdNode::interior(int(root.axis()), 1e30f, root.above_child()));
  const Blob b = Blob::open_memory(moved.bytes());
  EXPECT_NO_THROW(KdTreeView::from_blob(b, "kdtree"));
  EXPECT_THROW(b.verify(), BlobError);
}

TEST(KdTree, CommandLineTraceAgreesWithTheBvh) {
  KILN_REQUIRE_CORPUS();
  test::TempDir dir;
  const std::string blob = dir.file("x.kiln"), rays = dir.file("x.rays");
  ASSERT_EQ(run_kiln("build " + quoted(test::mesh_path("classic/teapot.obj")) +
                     " --accel kdtree --accel bvh -o " + quoted(blob))
                .exit_code,
            0);
  const auto dump = run_kiln("dump " + quoted(blob));
  EXPECT_NE(dump.out.find("empty bonus"), std::string::npos) << dump.out;
  ASSERT_EQ(run_kiln("rays " + quoted(blob) + " --count 5000 -o " + quoted(rays)).exit_code, 0);
  for (const char* any : {"", " --any-hit"}) {
    const std::string kd = dir.file("kd.hits"), bvh = dir.file("bvh.hits");
    ASSERT_EQ(run_kiln("trace " + quoted(blob) + " --accel kdtree --rays " + quoted(rays) +
                       " --out " + quoted(kd) + any)
                  .exit_code,
              0);
    ASSERT_EQ(run_kiln("trace " + quoted(blob) + " --accel bvh --rays " + quoted(rays) + " --out " +
                       quoted(bvh) + any)
                  .exit_code,
              0);
    const auto a = test::read_file(kd), b = test::read_file(bvh);
    ASSERT_EQ(a.size(), b.size());
    std::size_t disagreements = 0;
    for (std::size_t i = 0; i < a.size(); i += sizeof(Hit)) {
      Hit x, y;
      std::memcpy(&x, a.data() + i, sizeof x);
      std::memcpy(&y, b.data() + i, sizeof y);
      disagreements += (x.prim == kNoHit) != (y.prim == kNoHit);
      if (*any == 0 && x.prim != kNoHit && y.prim != kNoHit)
        disagreements += std::fabs(x.t - y.t) > 1e-5f * std::fabs(y.t);
    }
    EXPECT_EQ(disagreements, 0u) << any;
  }
}

}  // namespace
}  // namespace kiln
