// Closest point, point inside and box queries on the BVH against brute force.
#include <cmath>
#include <random>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/triangle_geometry.hpp"
#include "proximity_fixtures.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

using format::Double3;
using format::Float3;
using namespace kiln::test;

struct Built {
  FlatBvh flat;
  BvhView view() const { return BvhView(flat.nodes, flat.triangles, flat.prim_ids); }
};

Built build(const Scene& scene, BvhBuilder builder) {
  BvhBuildOptions o;
  o.builder = builder;
  return {build_bvh(scene, o)};
}

const char* kClosedMeshes[] = {"classic/spot.obj", "classic/fandisk.obj", "assimp/OBJ/box.obj"};

TEST(Proximity, ClosestPointMatchesBruteForce) {
  KILN_REQUIRE_CORPUS();
  for (const char* mesh :
       {"classic/teapot.obj", "classic/spot.obj", "assimp/STL/Spider_binary.stl"}) {
    SCOPED_TRACE(mesh);
    const Scene scene = import_scene({test::mesh_path(mesh)}, 2);
    const auto points = sample_points(scene, 10000, 5);
    std::vector<double> expected(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) expected[i] = brute_closest(scene, points[i]);
    for (const auto builder : {BvhBuilder::kBinned, BvhBuilder::kSpatial}) {
      const Built b = build(scene, builder);
      std::size_t wrong = 0;
      for (std::size_t i = 0; i < points.size(); ++i) {
        const ClosestPoint c = closest_point(b.view(), points[i]);
        ASSERT_NE(c.prim, kNoHit);
        if (std::fabs(double(c.distance) - expected[i]) > 1e-6 * expected[i] + 1e-30) ++wrong;
        // The reported point is on the reported triangle at the reported distance.
        double v, w;
        const Double3 q =
            closest_on_triangle(to_d(points[i]), corner(scene, c.prim, 0), corner(scene, c.prim, 1),
                                corner(scene, c.prim, 2), v, w);
        EXPECT_NEAR(q.x, c.point.x, 1e-5 * (1 + std::fabs(q.x)));
      }
      EXPECT_EQ(wrong, 0u) << bvh_builder_name(builder);
      // max_distance prunes: nothing closer than the bound is missed, nothing farther returned.
      const float bound = float(expected[0]) * 0.5f;
      EXPECT_EQ(closest_point(b.view(), points[0], bound).prim, kNoHit);
      EXPECT_NE(closest_point(b.view(), points[0], float(expected[0]) * 1.01f).prim, kNoHit);
    }
  }
}

TEST(Proximity, InsideMatchesWindingNumberOnClosedMeshes) {
  KILN_REQUIRE_CORPUS();
  for (const char* mesh : kClosedMeshes) {
    SCOPED_TRACE(mesh);
    BuildOptions options;
    options.inputs = {test::mesh_path(mesh)};
    const Scene scene = import_scene(options.inputs, 2);
    ASSERT_TRUE(edge_topology(scene).closed());
    const auto points = sample_points(scene, 10000, 11);
    std::vector<bool> expected(points.size());
    std::size_t inside_count = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
      expected[i] = winding_number(scene, points[i]) > 0.5;
      inside_count += expected[i];
    }
    EXPECT_GT(inside_count, 1000u);  // the test exercises both answers
    for (const auto builder : {BvhBuilder::kBinned, BvhBuilder::kSpatial}) {
      const Built b = build(scene, builder);
      std::size_t wrong = 0;
      for (std::size_t i = 0; i < points.size(); ++i)
        wrong += point_inside(b.view(), points[i]) != expected[i];
      EXPECT_EQ(wrong, 0u) << bvh_builder_name(builder);
    }
  }
}

TEST(Proximity, MeshClosednessIsReported) {
  KILN_REQUIRE_CORPUS();
  EXPECT_TRUE(edge_topology(import_scene({test::mesh_path("classic/spot.obj")}, 1)).closed());
  const auto bunny =
      edge_topology(import_scene({test::mesh_path("stanford/stanford-bunny.obj.zst")}, 1));
  EXPECT_FALSE(bunny.closed());  // the scanned bunny has holes in its base
  EXPECT_GT(bunny.boundary_edges, 0u);
}

TEST(Proximity, BoxQueryMatchesBruteForce) {
  KILN_REQUIRE_CORPUS();
  for (const char* mesh : {"classic/teapot.obj", "stanford/stanford-bunny.obj.zst"}) {
    SCOPED_TRACE(mesh);
    const Scene scene = import_scene({test::mesh_path(mesh)}, 2);
    const auto boxes = query_boxes(scene, 200, 3);
    for (const auto builder : {BvhBuilder::kBinned, BvhBuilder::kSpatial}) {
      const Built b = build(scene, builder);
      std::vector<std::uint32_t> got;
      for (std::size_t q = 0; q < boxes.size(); ++q) {
        triangles_in_box(b.view(), boxes[q].lo, boxes[q].hi, got);
        ASSERT_EQ(got, brute_box(scene, boxes[q].lo, boxes[q].hi))
            << "box " << q << " " << bvh_builder_name(builder);
      }
    }
  }
}

TEST(Proximity, TriangleBoxTestKnownCases) {
  const Double3 lo{0, 0, 0}, hi{1, 1, 1};
  EXPECT_TRUE(triangle_overlaps_box({0.5, 0.5, 0.5}, {5, 0.5, 0.5}, {0.5, 5, 0.5}, lo,
                                    hi));  // corner inside
  EXPECT_TRUE(triangle_overlaps_box({-1, -1, 0.5}, {3, -1, 0.5}, {-1, 3, 0.5}, lo,
                                    hi));  // box inside triangle
  EXPECT_FALSE(triangle_overlaps_box({2, 2, 2}, {3, 2, 2}, {2, 3, 2}, lo, hi));  // far away
  EXPECT_FALSE(
      triangle_overlaps_box({1.5, 0, -1}, {3, 0, 3}, {1.5, 3, -1}, lo, hi));  // only boxes overlap
  EXPECT_TRUE(triangle_overlaps_box({1, 0, 0}, {2, 0, 0}, {1, 1, 0}, lo, hi));  // touching face
  // Every face projection overlaps, yet the triangle passes beside the box's x = y = 1 edge.
  EXPECT_FALSE(triangle_overlaps_box({2.6, -0.5, 0.5}, {-0.5, 2.6, 0.5}, {-0.5, 2.6, 0.6}, lo, hi));
}

}  // namespace
}  // namespace kiln
