// Every mesh of the shared corpus: imported triangle counts against the figures in its
// MANIFEST.md (counted there by an independent parser), then a round trip through the blob,
// raw and zstd-compressed.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/runtime/aligned_buffer.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/bvh_wide.hpp"
#include "kiln/runtime/kdtree.hpp"
#include "kiln/runtime/point_tree.hpp"
#include "kiln/runtime/ray_structure.hpp"
#include "kiln/tools/ray_generator.hpp"
#include "ray_fixtures.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

struct CorpusMesh {
  const char* path;
  std::uint64_t faces_in_file;  // MANIFEST.md (glTF: instances expanded, scene table)
  std::uint64_t kept;           // after dropping zero-area triangles
};

// `kept` equals `faces_in_file` minus the zero-area triangles MANIFEST.md's scene table lists,
// except where a comment says otherwise.
const CorpusMesh kCorpus[] = {
    {"assimp/3MF/box.3mf", 12, 12},
    {"assimp/OBJ/WusonOBJ.obj", 3732, 3732},
    {"assimp/OBJ/box.obj", 12, 12},
    {"assimp/OBJ/box_UTF16BE.obj", 12, 12},
    {"assimp/OBJ/box_without_lineending.obj", 12, 12},
    {"assimp/OBJ/concave_polygon.obj", 64, 64},
    {"assimp/OBJ/cube_usemtl.obj", 12, 12},
    {"assimp/OBJ/multiple_spaces.obj", 1, 1},
    {"assimp/OBJ/spider.obj", 1368, 1312},  // same 56 zero-area facets as Spider_binary.stl
    {"assimp/OBJ/testmixed.obj", 12, 12},
    {"assimp/OFF/Cube.off", 12, 12},
    {"assimp/OFF/Wuson.off", 3732, 3732},
    {"assimp/PLY/Wuson.ply", 3732, 3732},
    {"assimp/PLY/cube.ply", 12, 12},
    {"assimp/PLY/cube_binary.ply", 12, 12},
    {"assimp/PLY/cube_uv.ply", 12, 12},
    {"assimp/PLY/float-color.ply", 1, 1},
    {"assimp/STL/3DSMaxExport.STL", 2000, 2000},
    {"assimp/STL/Spider_ascii.stl", 1368, 1312},
    {"assimp/STL/Spider_binary.stl", 1368, 1312},
    {"assimp/STL/Wuson.stl", 3732, 3732},
    {"assimp/STL/sphereWithHole.stl", 285, 285},
    {"assimp/STL/triangle.stl", 1, 1},
    {"assimp/STL/triangle_with_empty_solid.stl", 1, 1},
    {"assimp/STL/triangle_with_two_solids.stl", 2, 2},
    {"assimp/glTF2/BoxTextured-glTF-Binary/BoxTextured.glb", 12, 12},
    {"assimp/glTF2/BoxTextured-glTF/BoxTextured.gltf", 12, 12},
    {"classic/beast.obj.zst", 64618, 64618},
    {"classic/fandisk.obj", 12946, 12946},
    {"classic/ogre.obj.zst", 124008, 124004},  // 4 faces repeat a vertex (not in the table)
    {"classic/spot.obj", 5856, 5856},
    {"classic/suzanne.obj", 968, 968},
    {"classic/teapot.obj", 6320, 6320},
    {"gltf/2CylinderEngine-glTF-Binary/2CylinderEngine.glb", 121496, 110336},
    // MANIFEST.md lists 0 zero-area here, but Draco's position quantisation makes 13 triangles
    // with two identical corners (e.g. two at (13.3409, -33.4423, 9.99436)); they are dropped.
    {"gltf/2CylinderEngine-glTF-Draco/2CylinderEngine.gltf", 110336, 110323},
    {"gltf/Box-glTF-Draco-Binary/Box_Draco.glb", 12, 12},
    {"stanford/Lucy100k.ply", 100000, 100000},
    {"stanford/armadillo_86k.obj.zst", 86482, 86482},
    {"stanford/bun_zipper.ply.zst", 69451, 69451},
    {"stanford/dragon_100k.obj.zst", 100000, 100000},
    // Raw Draco bitstream, quantised: 105,118 of its triangles collapse to zero area.
    {"stanford/dragon_871k.drc", 871306, 766188},
    {"stanford/happy_buddha_113k.obj.zst", 112876, 112876},
    {"stanford/stanford-bunny.obj.zst", 69451, 69451},
};

void PrintTo(const CorpusMesh& mesh, std::ostream* out) {
  *out << mesh.path;
}

void expect_blob_matches_scene(const Scene& scene, const Blob& blob) {
  const InputInfo& input = blob.input();
  EXPECT_EQ(input.kind, InputKind::kTriangles);
  ASSERT_EQ(input.triangle_count, scene.triangles.size());
  ASSERT_EQ(input.vertex_count, scene.positions.size());
  EXPECT_EQ(input.input_triangle_count, scene.input_triangle_count);
  EXPECT_EQ(input.degenerate_triangles_dropped, scene.degenerate_triangles_dropped);
  EXPECT_EQ(input.has_normals, !scene.normals.empty());
  ASSERT_EQ(blob.positions().size(), scene.positions.size());
  EXPECT_EQ(
      0, std::memcmp(blob.positions().data(), scene.positions.data(), scene.positions.size() * 12));
  ASSERT_EQ(blob.triangles().size(), scene.triangles.size());
  EXPECT_EQ(
      0, std::memcmp(blob.triangles().data(), scene.triangles.data(), scene.triangles.size() * 12));
  ASSERT_EQ(blob.triangle_mesh_ids().size(), scene.triangle_mesh.size());
  EXPECT_TRUE(std::equal(scene.triangle_mesh.begin(), scene.triangle_mesh.end(),
                         blob.triangle_mesh_ids().begin()));
  ASSERT_EQ(blob.normals().size(), scene.normals.size());
  if (!scene.normals.empty()) {
    EXPECT_EQ(0,
              std::memcmp(blob.normals().data(), scene.normals.data(), scene.normals.size() * 12));
  }
  ASSERT_EQ(blob.mesh_count(), scene.meshes.size());
  for (std::uint32_t i = 0; i < scene.meshes.size(); ++i) {
    const MeshInfo mesh = blob.mesh(i);
    EXPECT_EQ(mesh.name, scene.meshes[i].name);
    EXPECT_EQ(mesh.first_triangle, scene.meshes[i].first_triangle);
    EXPECT_EQ(mesh.triangle_count, scene.meshes[i].triangle_count);
    EXPECT_EQ(mesh.first_vertex, scene.meshes[i].first_vertex);
    EXPECT_EQ(mesh.vertex_count, scene.meshes[i].vertex_count);
  }
  const auto sources = blob.sources();
  ASSERT_EQ(sources.size(), scene.sources.size());
  EXPECT_EQ(sources[0].xxh3, scene.sources[0].xxh3);
  EXPECT_EQ(sources[0].size, scene.sources[0].size);
  EXPECT_EQ(input.bounds.min.x, scene.bounds.min.x);
  EXPECT_EQ(input.bounds.max.z, scene.bounds.max.z);
}

class CorpusTest : public ::testing::TestWithParam<CorpusMesh> {};

TEST_P(CorpusTest, ImportCountsMatchManifestAndRoundTrip) {
  KILN_REQUIRE_CORPUS();
  const CorpusMesh& expected = GetParam();
  const Scene scene = import_scene({test::mesh_path(expected.path)}, 2);
  EXPECT_EQ(scene.input_triangle_count, expected.faces_in_file);
  EXPECT_EQ(scene.triangles.size(), expected.kept);
  EXPECT_EQ(scene.degenerate_triangles_dropped, expected.faces_in_file - expected.kept);

  for (const bool compress : {false, true}) {
    SCOPED_TRACE(compress ? "zstd" : "raw");
    BuildOptions options;
    options.inputs = {test::mesh_path(expected.path)};
    options.compression.enabled = compress;
    const std::vector<std::byte> bytes = compile_blob(scene, options);
    AlignedBuffer aligned(bytes.size(), 64);
    std::memcpy(aligned.data(), bytes.data(), bytes.size());
    const Blob blob = Blob::open_memory(aligned.bytes());
    EXPECT_NO_THROW(blob.verify());
    expect_blob_matches_scene(scene, blob);
  }
}

// The scene compiled with default structures of the given kinds, ready for open_memory.
AlignedBuffer compile_with(const Scene& scene, const std::vector<std::string>& kinds) {
  BuildOptions options;
  options.inputs = {"corpus"};
  for (const auto& kind : kinds) options.structures.push_back(resolve_structure_request(kind, {}));
  return test::aligned_copy(compile_blob(scene, options));
}

// Every mesh through the ray structures: the k-d tree and the BVH in one blob (verified), and
// the same closest and any hits from both on primary and diffuse rays.
TEST_P(CorpusTest, KdTreeTracesLikeTheBvh) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({test::mesh_path(GetParam().path)}, 2);
  const AlignedBuffer aligned = compile_with(scene, {"kdtree", "bvh:width=2"});
  const Blob blob = Blob::open_memory(aligned.bytes());
  ASSERT_NO_THROW(blob.verify());
  const KdTreeView kdtree = KdTreeView::from_blob(blob, "kdtree");
  const BvhView bvh = BvhView::from_blob(blob, "bvh");
  const format::Float3 lo = scene.bounds.min, hi = scene.bounds.max;
  for (const RayKind kind : {RayKind::kPrimary, RayKind::kDiffuse}) {
    const auto rays =
        generate_rays({bvh, blob.positions(), blob.triangles(), lo, hi}, kind, 2000, 3, 2);
    for (const bool any_hit : {false, true}) {
      std::vector<Hit> a(rays.size()), b(rays.size());
      trace_rays(kdtree, rays, a, any_hit, 2);
      trace_rays(bvh, rays, b, any_hit, 2);
      std::size_t disagreements = 0;
      for (std::size_t i = 0; i < rays.size(); ++i) {
        disagreements += (a[i].prim == kNoHit) != (b[i].prim == kNoHit);
        if (!any_hit && a[i].prim != kNoHit && b[i].prim != kNoHit)
          disagreements += std::fabs(a[i].t - b[i].t) > 1e-5f * std::fabs(b[i].t);
      }
      EXPECT_EQ(disagreements, 0u) << (any_hit ? "any hit" : "closest hit");
    }
  }
}

// Every mesh through the wide layouts: each kernel the CPU has, on 4-, 8- and 16-wide nodes, gives
// bit-identical hits to the scalar kernel, and the same hits as the binary BVH (hit/miss equal,
// t within 1e-6 relative, the primitive equal unless another one lies at exactly that t).
TEST_P(CorpusTest, WideKernelsTraceLikeTheBinaryBvh) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({test::mesh_path(GetParam().path)}, 2);
  const AlignedBuffer aligned =
      compile_with(scene, {"bvh:width=2,name=b2", "bvh:width=4,name=b4", "sbvh:width=8,name=s8",
                           "bvh:width=8,boxes=u8,name=q8", "sbvh:width=4,boxes=u8,name=q4",
                           "bvh:width=16,name=b16"});
  const Blob blob = Blob::open_memory(aligned.bytes());
  ASSERT_NO_THROW(blob.verify());
  const BvhView binary = BvhView::from_blob(blob, "b2");
  const format::Float3 lo = scene.bounds.min, hi = scene.bounds.max;
  for (const RayKind kind : {RayKind::kPrimary, RayKind::kDiffuse, RayKind::kShadow}) {
    const auto rays =
        generate_rays({binary, blob.positions(), blob.triangles(), lo, hi}, kind, 1500, 5, 2);
    std::vector<Hit> expected(rays.size()), reference(rays.size());
    trace_rays(binary, rays, expected, false, 2);
    for (const char* name : {"b4", "s8", "q8", "q4", "b16"}) {
      trace_rays(BvhWideView::from_blob(blob, name, BvhKernel::kScalar), rays, reference, false, 2);
      std::size_t disagreements = 0;
      for (std::size_t i = 0; i < rays.size(); ++i) {
        const Hit &e = expected[i], &g = reference[i];
        bool ok = e.hit() == g.hit();
        if (ok && e.hit())
          ok = std::fabs(g.t - e.t) <= 1e-6f * std::fabs(e.t) &&
               (g.prim == e.prim || test::tri_t(scene, g.prim, rays[i], INFINITY) == e.t);
        disagreements += !ok;
      }
      EXPECT_EQ(disagreements, 0u) << name << " against the binary BVH";
      for (const BvhKernel k : {BvhKernel::kSse, BvhKernel::kAvx2, BvhKernel::kAvx512}) {
        if (!bvh_kernel_supported(k)) continue;
        const BvhWideView view = BvhWideView::from_blob(blob, name, k);
        std::vector<Hit> closest(rays.size()), any(rays.size());
        trace_rays(view, rays, closest, false, 2);
        trace_rays(view, rays, any, true, 2);
        EXPECT_EQ(0, std::memcmp(closest.data(), reference.data(), rays.size() * sizeof(Hit)))
            << name << " " << bvh_kernel_name(k) << " against the scalar kernel";
        std::size_t any_wrong = 0;
        for (std::size_t i = 0; i < rays.size(); ++i)
          any_wrong +=
              any[i].hit() != closest[i].hit() || (any[i].hit() && any[i].t < closest[i].t);
        EXPECT_EQ(any_wrong, 0u) << name << " " << bvh_kernel_name(k) << " any hit";
      }
    }
  }
}

// Every mesh through the acceptance build (`--accel kdtree --accel points`): every query family
// answers from that blob alone. kNN and radius equal brute force; closest, inside and box on the
// k-d tree equal the BVH's (each checked against brute force on fewer meshes elsewhere).
TEST_P(CorpusTest, EveryQueryAnswersFromKdTreeAndPointTree) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({test::mesh_path(GetParam().path)}, 2);
  const AlignedBuffer aligned = compile_with(scene, {"kdtree", "points"});
  const Blob blob = Blob::open_memory(aligned.bytes());
  ASSERT_NO_THROW(blob.verify());
  const KdTreeView kdtree = KdTreeView::from_blob(blob, "kdtree");
  const PointTreeView points = PointTreeView::from_blob(blob, "points");
  const FlatBvh flat = build_bvh(scene, {});
  const BvhView bvh(flat.nodes, flat.triangles, flat.prim_ids);

  std::mt19937 rng(17);
  const format::Float3 lo = scene.bounds.min, hi = scene.bounds.max;
  const float size = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
  std::uniform_real_distribution<float> unit(-0.1f, 1.1f);
  auto random_point = [&] {
    return format::Float3{lo.x + (hi.x - lo.x) * unit(rng), lo.y + (hi.y - lo.y) * unit(rng),
                          lo.z + (hi.z - lo.z) * unit(rng)};
  };
  std::size_t knn_wrong = 0, radius_wrong = 0, closest_wrong = 0, inside_wrong = 0, box_wrong = 0;
  std::vector<Neighbor> found(8), within, all;
  std::vector<std::uint32_t> kd_ids, bvh_ids;
  for (int i = 0; i < 150; ++i) {
    const format::Float3 q = random_point();
    all.clear();
    for (std::uint32_t v = 0; v < scene.positions.size(); ++v) {
      const auto& p = scene.positions[v];
      const float dx = p.x - q.x, dy = p.y - q.y, dz = p.z - q.z;
      all.push_back({v, (dx * dx + dy * dy) + dz * dz});
    }
    std::sort(all.begin(), all.end(), closer);
    const std::size_t n = points.nearest(q, found);
    knn_wrong += n != std::min<std::size_t>(8, all.size());
    for (std::size_t j = 0; j < n; ++j) knn_wrong += found[j].id != all[j].id;
    const float radius = 0.05f * size;
    points.within_radius(q, radius, within);
    std::size_t expected = 0;
    while (expected < all.size() && all[expected].distance2 <= radius * radius) ++expected;
    radius_wrong += within.size() != expected;
    for (std::size_t j = 0; j < std::min(expected, within.size()); ++j)
      radius_wrong += within[j].id != all[j].id;

    const ClosestPoint a = closest_point(kdtree, q), b = closest_point(bvh, q);
    closest_wrong += a.distance != b.distance;
    inside_wrong += point_inside(kdtree, q) != point_inside(bvh, q);
    const format::Float3 half{0.04f * size, 0.04f * size, 0.04f * size};
    const format::Float3 box_lo{q.x - half.x, q.y - half.y, q.z - half.z};
    const format::Float3 box_hi{q.x + half.x, q.y + half.y, q.z + half.z};
    triangles_in_box(kdtree, box_lo, box_hi, kd_ids);
    triangles_in_box(bvh, box_lo, box_hi, bvh_ids);
    box_wrong += kd_ids != bvh_ids;
  }
  EXPECT_EQ(knn_wrong, 0u);
  EXPECT_EQ(radius_wrong, 0u);
  EXPECT_EQ(closest_wrong, 0u);
  EXPECT_EQ(inside_wrong, 0u);
  EXPECT_EQ(box_wrong, 0u);
}

std::string test_name(const ::testing::TestParamInfo<CorpusMesh>& info) {
  std::string name = info.param.path;
  for (auto& c : name)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  return name;
}

INSTANTIATE_TEST_SUITE_P(Corpus, CorpusTest, ::testing::ValuesIn(kCorpus), test_name);

// Several inputs flatten in command-line order: mesh table, source indices and triangle ranges.
TEST(CorpusTest, SeveralInputsFlattenInOrder) {
  KILN_REQUIRE_CORPUS();
  const std::vector<std::string> inputs = {
      test::mesh_path("classic/teapot.obj"),
      test::mesh_path("gltf/Box-glTF-Draco-Binary/Box_Draco.glb"),
      test::mesh_path("assimp/STL/Spider_binary.stl")};
  const Scene scene = import_scene(inputs, 2);
  EXPECT_EQ(scene.triangles.size(), 6320u + 12u + 1312u);
  ASSERT_EQ(scene.sources.size(), 3u);
  std::uint64_t next_triangle = 0;
  std::uint32_t previous_source = 0;
  for (const auto& mesh : scene.meshes) {
    EXPECT_EQ(mesh.first_triangle, next_triangle);
    EXPECT_GE(mesh.source_file, previous_source);
    next_triangle += mesh.triangle_count;
    previous_source = mesh.source_file;
  }
  EXPECT_EQ(next_triangle, scene.triangles.size());
  EXPECT_EQ(scene.meshes.front().source_file, 0u);
  EXPECT_EQ(scene.meshes.back().source_file, 2u);
  // The teapot alone gives the same first 6320 triangles: order does not depend on company.
  const Scene teapot = import_scene({inputs[0]}, 1);
  EXPECT_EQ(0, std::memcmp(teapot.triangles.data(), scene.triangles.data(),
                           teapot.triangles.size() * 12));
}

}  // namespace
}  // namespace kiln
