// Closest point, point inside and box queries on the SAH k-d tree against brute force and
// against the BVH's answers (the same semantics and tie rules).
#include <cmath>
#include <cstring>
#include <random>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/compiler/kdtree_builder.hpp"
#include "kiln/runtime/aligned_buffer.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/kdtree.hpp"
#include "proximity_fixtures.hpp"
#include "ray_fixtures.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

using format::Double3;
using format::Float3;
using namespace kiln::test;

struct Built {
  FlatKdTree kd;
  FlatBvh bvh;
  KdTreeView tree() const { return KdTreeView(kd.nodes, kd.prim_ids, kd.triangles, kd.bounds); }
  BvhView bvh_view() const { return BvhView(bvh.nodes, bvh.triangles, bvh.prim_ids); }
};

Built build(const Scene& scene) {
  return {build_kdtree(scene, KdTreeBuildOptions{}), build_bvh(scene, {})};
}

// Seeded points far from the scene: 2 to 20 diagonals away in every direction.
std::vector<Float3> far_points(const Scene& s, std::size_t count, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> scale(2, 20);
  const Double3 lo = to_d(s.bounds.min), size = to_d(s.bounds.max) - lo;
  const Double3 centre = lo + size * 0.5;
  const double diagonal = std::sqrt(dot(size, size));
  std::vector<Float3> points;
  for (std::size_t i = 0; i < count; ++i) {
    Double3 d{normal(rng), normal(rng), normal(rng)};
    d = d * (diagonal * scale(rng) / std::sqrt(dot(d, d)));
    points.push_back(to_f(centre + d));
  }
  return points;
}

// Closest points on the k-d tree against brute force (distance within 1e-6 relative, the
// reported point on the reported triangle) and against the BVH (same distance; the same triangle
// unless both lie at exactly the same distance, when the lower id wins on both). Stops after five
// failures.
void expect_closest_agrees(const Scene& scene, const Built& b, const std::vector<Float3>& points) {
  const KdTreeView tree = b.tree();
  const BvhView bvh = b.bvh_view();
  std::size_t failures = 0;
  for (std::size_t i = 0; i < points.size() && failures < 5; ++i) {
    const double expected = brute_closest(scene, points[i]);
    const ClosestPoint got = closest_point(tree, points[i]);
    const ClosestPoint other = closest_point(bvh, points[i]);
    bool ok = got.prim != kNoHit && other.prim != kNoHit;
    if (ok) {
      ok = std::fabs(double(got.distance) - expected) <= 1e-6 * expected + 1e-30 &&
           got.distance == other.distance;
      double v, w;
      const Double3 q =
          closest_on_triangle(to_d(points[i]), corner(scene, got.prim, 0),
                              corner(scene, got.prim, 1), corner(scene, got.prim, 2), v, w);
      ok = ok && std::fabs(q.x - got.point.x) <= 1e-5 * (1 + std::fabs(q.x)) &&
           std::fabs(q.y - got.point.y) <= 1e-5 * (1 + std::fabs(q.y)) &&
           std::fabs(q.z - got.point.z) <= 1e-5 * (1 + std::fabs(q.z));
      if (got.prim != other.prim)
        ok = ok && triangle_distance(scene, got.prim, points[i]) ==
                       triangle_distance(scene, other.prim, points[i]);
    }
    if (!ok) {
      ++failures;
      ADD_FAILURE() << "point " << i << " (" << points[i].x << ", " << points[i].y << ", "
                    << points[i].z << "): brute force " << expected << ", k-d tree prim "
                    << got.prim << " at " << got.distance << ", bvh prim " << other.prim << " at "
                    << other.distance;
    }
  }
}

TEST(KdTreeProximity, ClosestPointMatchesBruteForceAndTheBvh) {
  KILN_REQUIRE_CORPUS();
  for (const char* mesh :
       {"classic/teapot.obj", "classic/spot.obj", "assimp/STL/Spider_binary.stl"}) {
    SCOPED_TRACE(mesh);
    const Scene scene = import_scene({test::mesh_path(mesh)}, 2);
    const Built b = build(scene);
    auto points = sample_points(scene, 10000, 5);  // near, far and just off the surface
    const auto far = far_points(scene, 1000, 6);   // well outside the root cell
    points.insert(points.end(), far.begin(), far.end());
    expect_closest_agrees(scene, b, points);
  }
}

TEST(KdTreeProximity, ClosestPointMatchesBruteForceOnGeneratedWorstCases) {
  for (const auto& [name, scene] : worst_cases()) {
    SCOPED_TRACE(name);
    const Built b = build(scene);
    auto points = sample_points(scene, 2000, 7);
    const auto far = far_points(scene, 200, 8);
    points.insert(points.end(), far.begin(), far.end());
    expect_closest_agrees(scene, b, points);
  }
}

TEST(KdTreeProximity, ClosestPointRespectsMaxDistance) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({test::mesh_path("classic/teapot.obj")}, 2);
  const Built b = build(scene);
  const KdTreeView tree = b.tree();
  auto points = sample_points(scene, 300, 9);
  const auto far = far_points(scene, 100, 10);
  points.insert(points.end(), far.begin(), far.end());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const ClosestPoint unbounded = closest_point(tree, points[i]);
    ASSERT_NE(unbounded.prim, kNoHit);
    // Nothing farther than the bound is returned; nothing within it is missed.
    const ClosestPoint too_short = closest_point(tree, points[i], unbounded.distance * 0.5f);
    EXPECT_EQ(too_short.prim, kNoHit) << i;
    EXPECT_EQ(too_short.distance, INFINITY) << i;
    const ClosestPoint enough = closest_point(tree, points[i], unbounded.distance * 1.01f);
    EXPECT_EQ(enough.prim, unbounded.prim) << i;
    EXPECT_EQ(enough.distance, unbounded.distance) << i;
    EXPECT_EQ(closest_point(b.bvh_view(), points[i], unbounded.distance * 0.5f).prim, kNoHit);
  }
}

// point_inside on the k-d tree against the generalised winding number and against the BVH.
void expect_inside_agrees(const Scene& scene) {
  ASSERT_TRUE(edge_topology(scene).closed());
  const Built b = build(scene);
  const KdTreeView tree = b.tree();
  const BvhView bvh = b.bvh_view();
  const auto points = sample_points(scene, 10000, 11);
  std::size_t inside_count = 0, wrong = 0, differs_from_bvh = 0;
  for (const Float3& p : points) {
    const bool expected = winding_number(scene, p) > 0.5;
    const bool got = point_inside(tree, p);
    inside_count += expected;
    wrong += got != expected;
    differs_from_bvh += got != point_inside(bvh, p);
  }
  EXPECT_GT(inside_count, 1000u);  // the test exercises both answers
  EXPECT_EQ(wrong, 0u);
  EXPECT_EQ(differs_from_bvh, 0u);
}

TEST(KdTreeProximity, InsideMatchesWindingNumberOnClosedMeshes) {
  KILN_REQUIRE_CORPUS();
  for (const char* mesh : {"classic/spot.obj", "classic/fandisk.obj", "assimp/OBJ/box.obj"}) {
    SCOPED_TRACE(mesh);
    expect_inside_agrees(import_scene({test::mesh_path(mesh)}, 2));
  }
}

TEST(KdTreeProximity, InsideMatchesWindingNumberOnAnIcosphere) {
  expect_inside_agrees(icosphere(3));
}

TEST(KdTreeProximity, BoxQueryMatchesBruteForce) {
  KILN_REQUIRE_CORPUS();
  for (const char* mesh : {"classic/teapot.obj", "stanford/stanford-bunny.obj.zst"}) {
    SCOPED_TRACE(mesh);
    const Scene scene = import_scene({test::mesh_path(mesh)}, 2);
    const Built b = build(scene);
    std::vector<std::uint32_t> got;
    const auto boxes = query_boxes(scene, 250, 3);
    std::size_t flat_hits = 0, outside_hits = 0;
    for (std::size_t q = 0; q < boxes.size(); ++q) {
      const QueryBox& box = boxes[q];
      triangles_in_box(b.tree(), box.lo, box.hi, got);
      ASSERT_EQ(got, brute_box(scene, box.lo, box.hi)) << "box " << q;
      const Float3 &lo = scene.bounds.min, &hi = scene.bounds.max;
      flat_hits +=
          !got.empty() && (box.lo.x == box.hi.x || box.lo.y == box.hi.y || box.lo.z == box.hi.z);
      outside_hits += !got.empty() && (box.lo.x < lo.x || box.lo.y < lo.y || box.lo.z < lo.z ||
                                       box.hi.x > hi.x || box.hi.y > hi.y || box.hi.z > hi.z);
    }
    EXPECT_GT(flat_hits, 10u);     // flat boxes through a vertex
    EXPECT_GT(outside_hits, 10u);  // boxes partly outside the scene bounds
    // The whole scene and more; a box beside it; an inverted box.
    const Float3 lo = scene.bounds.min, hi = scene.bounds.max;
    triangles_in_box(b.tree(), {lo.x - 1, lo.y - 1, lo.z - 1}, {hi.x + 1, hi.y + 1, hi.z + 1}, got);
    EXPECT_EQ(got.size(), scene.triangles.size());
    const float beyond = hi.x + (hi.x - lo.x);
    triangles_in_box(b.tree(), {beyond, lo.y, lo.z}, {beyond + 1, hi.y, hi.z}, got);
    EXPECT_TRUE(got.empty());
    triangles_in_box(b.tree(), hi, lo, got);
    EXPECT_TRUE(got.empty());
  }
}

TEST(KdTreeProximity, BoxQueryMatchesBruteForceOnGeneratedWorstCases) {
  for (const auto& [name, scene] : worst_cases()) {
    SCOPED_TRACE(name);
    const Built b = build(scene);
    std::vector<std::uint32_t> got;
    const auto boxes = query_boxes(scene, 100, 4);
    for (std::size_t q = 0; q < boxes.size(); ++q) {
      triangles_in_box(b.tree(), boxes[q].lo, boxes[q].hi, got);
      ASSERT_EQ(got, brute_box(scene, boxes[q].lo, boxes[q].hi)) << "box " << q;
    }
  }
}

// A blob holding only a k-d tree answers the three queries from its mapped sections.
TEST(KdTreeProximity, AnswersFromABlobWithOnlyAKdTree) {
  const Scene scene = icosphere(3);
  BuildOptions options;
  options.inputs = {"generated"};
  options.threads = 2;
  options.structures = {resolve_structure_request("kdtree", {})};
  const auto bytes = compile_blob(scene, options);
  AlignedBuffer aligned(bytes.size(), 64);
  std::memcpy(aligned.data(), bytes.data(), bytes.size());
  const Blob blob = Blob::open_memory(aligned.bytes());
  const KdTreeView tree = KdTreeView::from_blob(blob, "kdtree");
  const auto points = sample_points(scene, 500, 12);
  std::vector<std::uint32_t> got;
  for (const Float3& p : points) {
    const double expected = brute_closest(scene, p);
    EXPECT_NEAR(closest_point(tree, p).distance, expected, 1e-6 * expected);
    EXPECT_EQ(point_inside(tree, p), winding_number(scene, p) > 0.5);
  }
  for (const QueryBox& box : query_boxes(scene, 50, 13)) {
    triangles_in_box(tree, box.lo, box.hi, got);
    EXPECT_EQ(got, brute_box(scene, box.lo, box.hi));
  }
}

}  // namespace
}  // namespace kiln
