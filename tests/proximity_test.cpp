// Closest point, point inside and box queries on the BVH against brute force.
#include <cmath>
#include <random>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/runtime/proximity.hpp"
#include "kiln/runtime/triangle_geometry.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

using format::Float3;

struct Built {
  FlatBvh flat;
  BvhView view() const { return BvhView(flat.nodes, flat.triangles, flat.prim_ids); }
};

Built build(const Scene& scene, BvhBuilder builder) {
  BvhBuildOptions o;
  o.builder = builder;
  return {build_bvh(scene, o)};
}

Vec3d corner(const Scene& s, std::uint32_t prim, int k) {
  return to_d(s.positions[s.triangles[prim].v[k]]);
}

double brute_closest(const Scene& s, const Float3& p) {
  double best = INFINITY;
  for (std::uint32_t i = 0; i < s.triangles.size(); ++i) {
    double v, w;
    const Vec3d q =
        closest_on_triangle(to_d(p), corner(s, i, 0), corner(s, i, 1), corner(s, i, 2), v, w);
    best = std::min(best, std::sqrt(dot(q - to_d(p), q - to_d(p))));
  }
  return best;
}

// Generalised winding number (sum of signed solid angles, Van Oosterom & Strackee 1983).
double winding_number(const Scene& s, const Float3& p) {
  double total = 0;
  for (std::uint32_t i = 0; i < s.triangles.size(); ++i) {
    const Vec3d a = corner(s, i, 0) - to_d(p), b = corner(s, i, 1) - to_d(p),
                c = corner(s, i, 2) - to_d(p);
    const double la = std::sqrt(dot(a, a)), lb = std::sqrt(dot(b, b)), lc = std::sqrt(dot(c, c));
    const double numerator = dot(a, cross(b, c));
    const double denominator = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
    total += 2 * std::atan2(numerator, denominator);
  }
  return total / (4 * 3.14159265358979323846);
}

// Seeded points: uniform in the bounds grown by 25 % (near and far), plus points just off the
// surface on both sides (1e-3 of the diagonal along the face normal).
std::vector<Float3> sample_points(const Scene& s, std::size_t count, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  const Vec3d lo = to_d(s.bounds.min), hi = to_d(s.bounds.max), size = hi - lo;
  const double diagonal = std::sqrt(dot(size, size));
  std::vector<Float3> points;
  for (std::size_t i = 0; i < count; ++i) {
    Vec3d p;
    if (i % 2 == 0) {
      p = lo - size * 0.25 +
          Vec3d{size.x * 1.5 * unit(rng), size.y * 1.5 * unit(rng), size.z * 1.5 * unit(rng)};
    } else {
      const auto prim = std::uint32_t(unit(rng) * double(s.triangles.size())) % s.triangles.size();
      double r1 = unit(rng), r2 = unit(rng);
      if (r1 + r2 > 1) r1 = 1 - r1, r2 = 1 - r2;
      const Vec3d a = corner(s, prim, 0), b = corner(s, prim, 1), c = corner(s, prim, 2);
      Vec3d n = cross(b - a, c - a);
      n = n * (1 / std::sqrt(dot(n, n)));
      p = a + (b - a) * r1 + (c - a) * r2 + n * ((i % 4 == 1 ? 1e-3 : -1e-3) * diagonal);
    }
    points.push_back({float(p.x), float(p.y), float(p.z)});
  }
  return points;
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
        const Vec3d q =
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
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> unit(0, 1);
    const Vec3d lo = to_d(scene.bounds.min), size = to_d(scene.bounds.max) - lo;
    for (const auto builder : {BvhBuilder::kBinned, BvhBuilder::kSpatial}) {
      const Built b = build(scene, builder);
      std::vector<std::uint32_t> got;
      for (int q = 0; q < 200; ++q) {
        const double extent = q % 3 == 0 ? 0.3 : 0.05;  // large and small boxes
        const Vec3d c = lo + Vec3d{size.x * unit(rng), size.y * unit(rng), size.z * unit(rng)};
        const Vec3d half = Vec3d{size.x * extent * unit(rng), size.y * extent * unit(rng),
                                 size.z * extent * unit(rng)};
        const Vec3d blo = c - half, bhi = c + half;
        const Float3 flo{float(blo.x), float(blo.y), float(blo.z)},
            fhi{float(bhi.x), float(bhi.y), float(bhi.z)};
        std::vector<std::uint32_t> expected;
        for (std::uint32_t i = 0; i < scene.triangles.size(); ++i)
          if (triangle_overlaps_box(corner(scene, i, 0), corner(scene, i, 1), corner(scene, i, 2),
                                    to_d(flo), to_d(fhi)))
            expected.push_back(i);
        triangles_in_box(b.view(), flo, fhi, got);
        ASSERT_EQ(got, expected) << "box " << q << " " << bvh_builder_name(builder);
      }
    }
  }
}

TEST(Proximity, TriangleBoxTestKnownCases) {
  const Vec3d lo{0, 0, 0}, hi{1, 1, 1};
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
