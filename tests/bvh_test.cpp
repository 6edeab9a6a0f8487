// BVH builders and traversal against brute force (every ray against every triangle, with the
// same watertight test), on corpus meshes and generated worst cases.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <map>
#include <random>

#include "../compiler/src/bvh_splits.hpp"
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

// --- The SBVH's presorted reference arrays and its splits against plain recomputation ---

// Random triangles of mixed sizes (some long, some sharing a centroid coordinate).
Scene random_triangles(std::size_t n, std::uint32_t seed) {
  Scene scene;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> pos(-50.0f, 50.0f), size(0.05f, 4.0f);
  for (std::size_t i = 0; i < n; ++i) {
    const Float3 c{pos(rng), i % 5 == 0 ? 1.0f : pos(rng), pos(rng)};
    const float s = i % 9 == 0 ? 15.0f * size(rng) : size(rng);
    const auto base = std::uint32_t(scene.positions.size());
    scene.positions.push_back(c);
    scene.positions.push_back({c.x + s, c.y + 0.4f * s, c.z - 0.2f * s});
    scene.positions.push_back({c.x - 0.3f * s, c.y + s, c.z + 0.6f * s});
    scene.triangles.push_back({{base, base + 1, base + 2}});
  }
  return scene;
}

std::vector<PrimRef> triangle_refs(const Scene& scene) {
  std::vector<PrimRef> refs(scene.triangles.size());
  for (std::uint32_t i = 0; i < refs.size(); ++i) {
    for (const auto v : scene.triangles[i].v) refs[i].box.grow(scene.positions[v]);
    refs[i].prim = i;
  }
  return refs;
}

// The box around `refs` (with them, a node's input to the split searches).
format::Box3f refs_box(std::span<const PrimRef> refs) {
  format::Box3f box;
  for (const auto& ref : refs) box.grow(ref.box);
  return box;
}

SortedRefs presorted(std::span<const PrimRef> refs) {
  SortedRefs s;
  for (int a = 0; a < 3; ++a) sort_by_centroid(refs, a, s.axis[a]);
  return s;
}

// Each axis array sorted by (centroid, primitive id) and all three holding the same references.
void expect_presorted(const SortedRefs& s) {
  for (int a = 0; a < 3; ++a) {
    const auto& v = s.axis[a];
    ASSERT_EQ(v.size(), s.size());
    for (std::size_t i = 1; i < v.size(); ++i) {
      const float c0 = v[i - 1].box.centroid(a) + 0.0f, c1 = v[i].box.centroid(a) + 0.0f;
      ASSERT_TRUE(c0 < c1 || (c0 == c1 && v[i - 1].prim < v[i].prim))
          << "axis " << a << " at " << i;
    }
  }
  auto by_prim = [](std::vector<PrimRef> v) {
    std::sort(v.begin(), v.end(),
              [](const PrimRef& x, const PrimRef& y) { return x.prim < y.prim; });
    return v;
  };
  const auto ref = by_prim(s.axis[0]);
  for (int a = 1; a < 3; ++a) {
    const auto other = by_prim(s.axis[a]);
    ASSERT_EQ(0, std::memcmp(ref.data(), other.data(), ref.size() * sizeof(PrimRef))) << a;
  }
}

// Sorting is by (centroid, primitive id) whatever the input order (the radix sort above 2048
// references takes the id's digits too): shuffled references sort to the same arrays.
TEST(SbvhPresorted, SortByCentroidIgnoresTheInputOrder) {
  const Scene scene = random_triangles(5000, 9);
  std::vector<PrimRef> refs = triangle_refs(scene);
  const SortedRefs in_order = presorted(refs);
  expect_presorted(in_order);
  std::shuffle(refs.begin(), refs.end(), std::mt19937(4));
  const SortedRefs shuffled = presorted(refs);
  for (int a = 0; a < 3; ++a)
    EXPECT_EQ(0, std::memcmp(in_order.axis[a].data(), shuffled.axis[a].data(),
                             refs.size() * sizeof(PrimRef)))
        << a;
}

TEST(SbvhPresorted, ObjectSplitKeepsEveryAxisSortedAndSplitsAtTheSweepPrefix) {
  const Scene scene = random_triangles(3000, 3);
  const SortedRefs all = presorted(triangle_refs(scene));
  expect_presorted(all);
  for (int axis = 0; axis < 3; ++axis) {
    for (const std::size_t left_count : {std::size_t(1), std::size_t(1234), std::size_t(2999)}) {
      SortedRefs l, r;
      partition_object_split(all, axis, left_count, l, r);
      expect_presorted(l);
      expect_presorted(r);
      // The in-place form (the left child takes the parent's arrays) gives the same arrays.
      SortedRefs l2, r2;
      partition_object_split(SortedRefs(all), axis, left_count, l2, r2);
      for (int a = 0; a < 3; ++a) {
        ASSERT_EQ(l2.axis[a].size(), l.axis[a].size());
        ASSERT_EQ(r2.axis[a].size(), r.axis[a].size());
        EXPECT_EQ(0, std::memcmp(l2.axis[a].data(), l.axis[a].data(),
                                 l.axis[a].size() * sizeof(PrimRef)));
        EXPECT_EQ(0, std::memcmp(r2.axis[a].data(), r.axis[a].data(),
                                 r.axis[a].size() * sizeof(PrimRef)));
      }
      ASSERT_EQ(l.size(), left_count);
      ASSERT_EQ(r.size(), all.size() - left_count);
      // Brute force: the left child is the first left_count references on the split axis.
      std::vector<std::uint32_t> expected, got;
      for (std::size_t i = 0; i < left_count; ++i) expected.push_back(all.axis[axis][i].prim);
      for (const auto& ref : l.axis[(axis + 1) % 3]) got.push_back(ref.prim);
      std::sort(expected.begin(), expected.end());
      std::sort(got.begin(), got.end());
      EXPECT_EQ(got, expected);
    }
  }
}

TEST(SbvhPresorted, SpatialSplitChildrenStaySortedAndHoldEachTrianglesSides) {
  const Scene scene = random_triangles(2000, 5);
  const std::vector<PrimRef> refs = triangle_refs(scene);
  const SortedRefs all = presorted(refs);
  for (int axis = 0; axis < 3; ++axis) {
    const SpatialSplit split{0.0f, axis, 3.5f};
    SortedRefs l, r, parent = all;  // the left child takes the parent's arrays
    const std::size_t added = apply_spatial_split(split, parent, axis, scene, l, r);
    expect_presorted(l);
    expect_presorted(r);
    EXPECT_EQ(l.size() + r.size(), refs.size() + added);
    EXPECT_GT(added, 0u);
    // Brute force, triangle by triangle: whole on its side, or its pieces (or whole box) on
    // the sides it crosses, each within the exact clipped part.
    std::map<std::uint32_t, format::Box3f> left, right;
    for (const auto& ref : l.axis[0]) left[ref.prim] = ref.box;
    for (const auto& ref : r.axis[0]) right[ref.prim] = ref.box;
    for (const PrimRef& ref : refs) {
      const float lo = format::at(ref.box.min, axis), hi = format::at(ref.box.max, axis);
      const bool in_l = left.count(ref.prim), in_r = right.count(ref.prim);
      ASSERT_TRUE(in_l || in_r) << ref.prim;
      if (hi <= split.position) {
        ASSERT_TRUE(in_l && !in_r);
      }
      if (lo >= split.position) {
        ASSERT_TRUE(in_r && !in_l);
      }
      if (in_l && in_r) {
        format::Box3f cl, cr;
        split_reference(ref, axis, split.position, scene, cl, cr);
        EXPECT_EQ(0, std::memcmp(&left[ref.prim], &cl, sizeof cl)) << ref.prim;
        EXPECT_EQ(0, std::memcmp(&right[ref.prim], &cr, sizeof cr)) << ref.prim;
      } else {
        const format::Box3f& b = in_l ? left[ref.prim] : right[ref.prim];
        EXPECT_EQ(0, std::memcmp(&b, &ref.box, sizeof b)) << ref.prim;
      }
    }
  }
}

// The best spatial split by brute force: every bin plane, each reference clipped at it.
float brute_spatial_cost(const Scene& scene, std::span<const PrimRef> refs,
                         const format::Box3f& box, std::uint32_t k, int axis, std::uint32_t b) {
  const float lo = format::at(box.min, axis), extent = format::at(box.max, axis) - lo;
  const float plane = lo + (extent / float(k)) * float(b);
  format::Box3f l, r;
  std::size_t nl = 0, nr = 0;
  for (const PrimRef& ref : refs) {
    format::Box3f cl, cr;
    split_reference(ref, axis, plane, scene, cl, cr);
    if (format::at(ref.box.min, axis) < plane) l.grow(cl), ++nl;
    if (format::at(ref.box.max, axis) > plane) r.grow(cr), ++nr;
  }
  if (nl == 0 || nr == 0) return std::numeric_limits<float>::infinity();
  return 1.0f + (l.half_area() * float(nl) + r.half_area() * float(nr)) / box.half_area();
}

TEST(SbvhPresorted, SpatialSplitIsTheBruteForceBinOptimum) {
  // Node sizes in each of the policy's bin tiers, and below the smallest searched.
  for (const std::size_t n :
       {std::size_t(5), std::size_t(40), std::size_t(600), std::size_t(4200)}) {
    const Scene scene = random_triangles(n, 9);
    const std::vector<PrimRef> refs = triangle_refs(scene);
    const format::Box3f box = refs_box(refs);
    BvhBuildOptions o;
    o.builder = BvhBuilder::kSpatial;
    for (const std::uint32_t bins : {7u, 32u}) {
      o.bins = bins;
      for (const int object_axis : {-1, 0, 1, 2}) {
        const SpatialSplit found = find_spatial_split(refs, box, scene, o, object_axis);
        if (n < kMinSpatialRefs) {
          EXPECT_FALSE(found.valid());
          continue;
        }
        ASSERT_TRUE(found.valid());
        const std::uint32_t k = spatial_bin_count(n, bins);
        const unsigned axes = spatial_axes(box, object_axis);
        EXPECT_TRUE(axes >> found.axis & 1);
        if (object_axis >= 0) {
          EXPECT_TRUE(axes >> object_axis & 1);
        }
        float best = std::numeric_limits<float>::infinity();
        for (int a = 0; a < 3; ++a)
          if (axes >> a & 1)
            for (std::uint32_t b = 1; b < k; ++b)
              best = std::min(best, brute_spatial_cost(scene, refs, box, k, a, b));
        EXPECT_NEAR(found.cost, best, 1e-4f * best) << n << " refs, " << bins << " bins";
      }
    }
  }
}

TEST(SbvhPresorted, SpatialSearchStopsEarlyOnlyWhereNoPlaneBeatsTheBound) {
  // find_spatial_split's `to_beat` (the object split's cost) lets it stop before clipping where
  // a lower bound says no plane costs less. Against the full search: below the bound the same
  // split, bit for bit; at or above it either the same split or none. 40,000 references take
  // the chunked path.
  for (const std::size_t n : {std::size_t(40), std::size_t(600), std::size_t(40000)}) {
    const Scene scene = random_triangles(n, 21);
    const std::vector<PrimRef> refs = triangle_refs(scene);
    const format::Box3f box = refs_box(refs);
    BvhBuildOptions o;
    o.builder = BvhBuilder::kSpatial;
    const SpatialSplit full = find_spatial_split(refs, box, scene, o, 0, 2);
    ASSERT_TRUE(full.valid());
    const float inf = std::numeric_limits<float>::infinity();
    // Nothing costs less than 0: the search stops after the counting pass.
    EXPECT_FALSE(find_spatial_split(refs, box, scene, o, 0, 2, 0.0f).valid());
    for (const float to_beat :
         {full.cost * 0.9f, full.cost, std::nextafter(full.cost, inf), full.cost * 1.1f, inf}) {
      const SpatialSplit found = find_spatial_split(refs, box, scene, o, 0, 2, to_beat);
      if (full.cost < to_beat) {
        ASSERT_TRUE(found.valid()) << n << " refs, to beat " << to_beat;
      }
      if (found.valid()) {
        EXPECT_EQ(found.axis, full.axis);
        EXPECT_EQ(std::bit_cast<std::uint32_t>(found.position),
                  std::bit_cast<std::uint32_t>(full.position));
        EXPECT_EQ(std::bit_cast<std::uint32_t>(found.cost),
                  std::bit_cast<std::uint32_t>(full.cost));
      }
    }
  }
}

TEST(SbvhPresorted, SameTreeOnAnyThreadCountAboveTheChunkedBinningSize) {
  // Above 32768 references a node bins its spatial splits in fixed chunks, in parallel.
  const Scene scene = random_triangles(36000, 13);
  std::vector<FlatBvh> built;
  for (const unsigned threads : {1u, 2u, 8u})
    built.push_back(build(scene, BvhBuilder::kSpatial, threads));
  for (std::size_t i = 1; i < built.size(); ++i) {
    ASSERT_EQ(built[i].nodes.size(), built[0].nodes.size());
    EXPECT_EQ(0, std::memcmp(built[i].nodes.data(), built[0].nodes.data(),
                             built[0].nodes.size() * sizeof(format::BvhNode)));
    EXPECT_EQ(built[i].prim_ids, built[0].prim_ids);
  }
  EXPECT_GT(built[0].stats.duplication_factor, 1.0);  // spatial splits were taken
  // Every triangle in some leaf whose box overlaps its own.
  std::vector<bool> seen(scene.triangles.size());
  for (const format::BvhNode& node : built[0].nodes) {
    for (std::uint32_t j = 0; j < node.count; ++j) {
      const std::uint32_t t = built[0].prim_ids[node.offset + j];
      seen[t] = true;
      format::Box3f tb;
      for (const auto v : scene.triangles[t].v) tb.grow(scene.positions[v]);
      for (int a = 0; a < 3; ++a) {
        ASSERT_LE(node.min[a], format::at(tb.max, a));
        ASSERT_GE(node.max[a], format::at(tb.min, a));
      }
    }
  }
  EXPECT_EQ(std::count(seen.begin(), seen.end(), false), 0);
}

}  // namespace
}  // namespace kiln
