// The uniform and the two-level grid: the density rule, cell lists against brute-force
// triangle/box overlap, the DDA's cell order against brute-force slab intervals, the two-level
// grid against the uniform one, and degenerate scenes against brute force.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "kiln/compiler/grid_builder.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/grid.hpp"
#include "kiln/runtime/grid_dda.hpp"
#include "kiln/runtime/triangle_geometry.hpp"
#include "ray_fixtures.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

using format::Float3;
using namespace kiln::test;

GridView view_of(const FlatGrid& g) {
  return GridView(g.frame, {g.offsets, g.refs}, g.triangles);
}
NestedGridView nested_view_of(const FlatGrid& g) {
  return NestedGridView(g.frame, g.leaves, {g.offsets, g.refs}, g.triangles);
}

FlatGrid uniform(const Scene& scene, float density = 4.0f) {
  GridBuildOptions o;
  o.density = density;
  o.threads = 2;
  return build_grid(scene, o);
}

FlatGrid nested(const Scene& scene) {
  GridBuildOptions o;
  o.density = 0.0625f;
  o.leaf_density = 2.0f;
  o.threads = 2;
  return build_nested_grid(scene, o);
}

// Random small triangles in the unit cube, and a few long ones across it.
Scene scattered(std::size_t count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f), small(-0.05f, 0.05f);
  std::vector<Float3> p;
  std::vector<format::Triangle> t;
  for (std::size_t i = 0; i < count; ++i) {
    const Float3 c{unit(rng), unit(rng), unit(rng)};
    const float s = i % 16 == 0 ? 10.0f : 1.0f;
    add_triangle(p, t, {c.x + s * small(rng), c.y + s * small(rng), c.z + s * small(rng)},
                 {c.x + s * small(rng), c.y + s * small(rng), c.z + s * small(rng)},
                 {c.x + s * small(rng), c.y + s * small(rng), c.z + s * small(rng)});
  }
  return make_scene(std::move(p), std::move(t));
}

TEST(GridResolution, AboutDensityTimesTrianglesCellsAndCubic) {
  const float extent[3] = {1.0f, 2.0f, 4.0f};
  const auto res = grid_resolution(extent, 8000.0);
  const double cells = double(res[0]) * res[1] * res[2];
  EXPECT_GT(cells, 8000.0 * 0.7);
  EXPECT_LT(cells, 8000.0 * 1.4);
  double lo = INFINITY, hi = 0;
  for (int a = 0; a < 3; ++a) {
    lo = std::min(lo, double(extent[a]) / res[a]);
    hi = std::max(hi, double(extent[a]) / res[a]);
  }
  EXPECT_LT(hi / lo, 1.25) << res[0] << " " << res[1] << " " << res[2];
}

TEST(GridResolution, FlatAxisGetsOneCellAndCapsHold) {
  const float flat[3] = {1.0f, 1.0f, 0.0f};
  const auto res = grid_resolution(flat, 400.0);
  EXPECT_EQ(res[2], 1u);
  EXPECT_EQ(res[0], 20u);
  EXPECT_EQ(res[1], 20u);
  const float thin[3] = {1.0f, 1e-6f, 1e-6f};
  EXPECT_EQ(grid_resolution(thin, 1e9)[0], format::kGridMaxAxis);
  const float cube[3] = {1.0f, 1.0f, 1.0f};
  const auto capped = grid_resolution(cube, 1e12);
  EXPECT_LE(std::uint64_t(capped[0]) * capped[1] * capped[2], format::kGridMaxCells);
  EXPECT_EQ(grid_resolution(cube, 0.0), (std::array<std::uint32_t, 3>{1, 1, 1}));
}

// Every cell lists exactly the triangles the separating-axis test says meet its box, up to the
// builder's padding (a thousandth of a cell): never fewer, never a triangle farther away.
TEST(GridLists, MatchBruteForceTriangleBoxOverlap) {
  const Scene scene = scattered(300, 5);
  const FlatGrid g = uniform(scene, 2.0f);
  const GridView view = view_of(g);
  const GridFrame& f = g.frame;
  std::size_t bounding_box_only = 0;
  std::uint32_t c[3];
  for (c[2] = 0; c[2] < f.res[2]; ++c[2])
    for (c[1] = 0; c[1] < f.res[1]; ++c[1])
      for (c[0] = 0; c[0] < f.res[0]; ++c[0]) {
        format::Double3 lo, hi, lo_wide, hi_wide;
        for (int a = 0; a < 3; ++a) {
          at(lo, a) = f.plane(a, c[a]), at(hi, a) = f.plane(a, c[a] + 1);
          const double slack = (at(hi, a) - at(lo, a)) * 2e-3;
          at(lo_wide, a) = at(lo, a) - slack, at(hi_wide, a) = at(hi, a) + slack;
        }
        const auto refs = view.lists().cell(f.linear(c));
        for (std::uint32_t i = 0; i < g.triangles.size(); ++i) {
          const auto& t = g.triangles[i];
          const bool listed = std::binary_search(refs.begin(), refs.end(), i);
          const format::Double3 v0 = to_d(t.v0), v1 = to_d(t.v1), v2 = to_d(t.v2);
          if (triangle_overlaps_box(v0, v1, v2, lo, hi)) {
            EXPECT_TRUE(listed) << "triangle " << i << " missing from cell " << f.linear(c);
          } else if (listed) {
            EXPECT_TRUE(triangle_overlaps_box(v0, v1, v2, lo_wide, hi_wide)) << i;
          }
          format::Box3f box;
          box.grow(t.v0), box.grow(t.v1), box.grow(t.v2);
          const bool boxes_meet = box.min.x <= hi.x && box.max.x >= lo.x && box.min.y <= hi.y &&
                                  box.max.y >= lo.y && box.min.z <= hi.z && box.max.z >= lo.z;
          bounding_box_only += boxes_meet && !listed;
        }
      }
  EXPECT_GT(bounding_box_only, 0u) << "the exact test should drop some bounding-box overlaps";
}

// Brute force: the parameter interval of the ray in a cell's box, in double.
bool slab_interval(const GridFrame& f, const std::uint32_t c[3], const Ray& ray, double& t0,
                   double& t1) {
  t0 = ray.tmin, t1 = ray.tmax;
  const double org[3] = {ray.org.x, ray.org.y, ray.org.z},
               dir[3] = {ray.dir.x, ray.dir.y, ray.dir.z};
  for (int a = 0; a < 3; ++a) {
    const double lo = f.plane(a, c[a]), hi = f.plane(a, c[a] + 1);
    if (dir[a] == 0) {
      if (org[a] < lo || org[a] > hi) return false;
      continue;
    }
    double n = (lo - org[a]) / dir[a], x = (hi - org[a]) / dir[a];
    if (n > x) std::swap(n, x);
    t0 = std::max(t0, n), t1 = std::min(t1, x);
  }
  return t0 <= t1;
}

// The DDA visits, in order of entry, every cell the ray crosses for more than a sliver, and
// only cells the ray comes within rounding of.
TEST(GridDda, VisitsTheCellsTheRayCrossesInOrder) {
  const GridFrame f{{-1.0f, 0.5f, 2.0f}, {3.0f, 2.5f, 3.0f}, {7, 5, 3}};
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> around(-0.5f, 1.5f), unit(-1.0f, 1.0f);
  for (int i = 0; i < 2000; ++i) {
    const Float3 o{f.lo[0] + (f.hi[0] - f.lo[0]) * around(rng),
                   f.lo[1] + (f.hi[1] - f.lo[1]) * around(rng),
                   f.lo[2] + (f.hi[2] - f.lo[2]) * around(rng)};
    Float3 d{unit(rng), unit(rng), unit(rng)};
    if (i % 5 == 0)
      d = i % 15 == 0 ? Float3{0, 0, -1} : i % 15 == 5 ? Float3{1, 0, 0} : Float3{0, 1, 0};
    const Ray ray{o, 0.0f, d, INFINITY};
    std::vector<std::uint64_t> visited;
    std::vector<double> entries;
    walk_grid(f, make_grid_ray(ray), ray.tmin, ray.tmax,
              [&](const std::uint32_t c[3], float, float) {
                double t0, t1;
                EXPECT_TRUE(slab_interval(f, c, ray, t0, t1) || t0 <= t1 + 1e-5) << "ray " << i;
                visited.push_back(f.linear(c));
                entries.push_back(t0);
                return false;
              });
    for (std::size_t k = 1; k < entries.size(); ++k)
      EXPECT_LE(entries[k - 1], entries[k] + 1e-5) << "ray " << i;
    std::uint32_t c[3];
    for (c[2] = 0; c[2] < f.res[2]; ++c[2])
      for (c[1] = 0; c[1] < f.res[1]; ++c[1])
        for (c[0] = 0; c[0] < f.res[0]; ++c[0]) {
          double t0, t1;
          if (!slab_interval(f, c, ray, t0, t1) || t1 - t0 < 1e-4) continue;
          EXPECT_NE(std::find(visited.begin(), visited.end(), f.linear(c)), visited.end())
              << "ray " << i << " skipped cell " << f.linear(c);
        }
  }
}

void expect_both_agree_with_brute_force(const Scene& scene, std::size_t rays) {
  const auto batch = box_rays(scene, rays);
  const FlatGrid g = uniform(scene), n = nested(scene);
  expect_agrees_with_brute_force(scene, view_of(g), batch);
  expect_agrees_with_brute_force(scene, nested_view_of(n), batch);
}

// Same hits (t, and primitive up to ties), same any-hit verdicts, on the uniform and the
// two-level grid.
TEST(NestedGrid, HitsEqualTheUniformGrids) {
  const Scene scene = worst_cases().at("teapot_in_stadium");
  const FlatGrid flat_uniform = uniform(scene);
  const GridView u = view_of(flat_uniform);
  const FlatGrid flat = nested(scene);
  const NestedGridView n = nested_view_of(flat);
  EXPECT_GT(flat.leaves.size(), 1u);
  for (const Ray& ray : box_rays(scene, 3000)) {
    const Hit a = u.intersect(ray), b = n.intersect(ray);
    ASSERT_EQ(a.hit(), b.hit());
    EXPECT_EQ(a.t, b.t);
    if (a.prim != b.prim) {
      EXPECT_EQ(tri_t(scene, b.prim, ray, INFINITY), a.t);
    }
    EXPECT_EQ(u.occluded(ray), n.occluded(ray));
  }
}

TEST(GridDegenerate, FlatSceneSingleTriangleAndOneCrowdedCell) {
  {
    SCOPED_TRACE("flat");
    std::mt19937 rng(8);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    std::vector<Float3> p;
    std::vector<format::Triangle> t;
    for (int i = 0; i < 200; ++i) {
      const float x = unit(rng), y = unit(rng);
      add_triangle(p, t, {x, y, 0}, {x + 0.1f, y, 0}, {x, y + 0.1f, 0});
    }
    const Scene flat = make_scene(std::move(p), std::move(t));
    EXPECT_EQ(uniform(flat).frame.res[2], 1u);
    expect_both_agree_with_brute_force(flat, 2000);
  }
  {
    SCOPED_TRACE("single");
    std::vector<Float3> p;
    std::vector<format::Triangle> t;
    add_triangle(p, t, {0, 0, 0}, {1, 0, 0}, {0, 1, 1});
    const Scene one = make_scene(std::move(p), std::move(t));
    const FlatGrid g = uniform(one);
    EXPECT_LE(g.frame.cell_count(), 8u);
    expect_both_agree_with_brute_force(one, 1000);
  }
  {
    SCOPED_TRACE("crowded");
    // 2000 triangles through one point, and one far away: one cell holds nearly all of them.
    std::vector<Float3> p;
    std::vector<format::Triangle> t;
    for (int i = 0; i < 2000; ++i) {
      const float a = 0.001f * float(i);
      add_triangle(p, t, {0, 0, 0}, {1e-3f * std::cos(a), 1e-3f * std::sin(a), 1e-3f},
                   {1e-3f * std::cos(a + 0.5f), 1e-3f * std::sin(a + 0.5f), -1e-3f});
    }
    add_triangle(p, t, {10, 10, 10}, {11, 10, 10}, {10, 11, 10});
    const Scene crowded = make_scene(std::move(p), std::move(t));
    const FlatGrid g = uniform(crowded);
    EXPECT_GE(g.stats.largest_cell, 1900u);
    EXPECT_GT(nested(crowded).stats.cell_count, 1u);
    expect_both_agree_with_brute_force(crowded, 2000);
  }
}

// The proximity queries against the brute-force answers of the surface adapter's contract.
TEST(GridQueries, BoxQueryMatchesBruteForce) {
  const Scene scene = scattered(400, 9);
  const FlatGrid g = uniform(scene), n = nested(scene);
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> unit(-0.1f, 1.1f), size(0.0f, 0.3f);
  for (int q = 0; q < 100; ++q) {
    const Float3 lo{unit(rng), unit(rng), unit(rng)};
    const Float3 hi{lo.x + size(rng), lo.y + size(rng), lo.z + size(rng)};
    std::vector<std::uint32_t> expected, got;
    for (std::uint32_t i = 0; i < g.triangles.size(); ++i) {
      const auto& t = g.triangles[i];
      if (triangle_overlaps_box(to_d(t.v0), to_d(t.v1), to_d(t.v2), to_d(lo), to_d(hi)))
        expected.push_back(i);
    }
    triangles_in_box(view_of(g), lo, hi, got);
    EXPECT_EQ(got, expected);
    triangles_in_box(nested_view_of(n), lo, hi, got);
    EXPECT_EQ(got, expected);
    const ClosestPoint a = closest_point(view_of(g), lo), b = closest_point(nested_view_of(n), lo);
    double best = INFINITY;
    for (const auto& t : g.triangles) {
      double v, w;
      const auto c = closest_on_triangle(to_d(lo), to_d(t.v0), to_d(t.v1), to_d(t.v2), v, w);
      best = std::min(best, dot(c - to_d(lo), c - to_d(lo)));
    }
    EXPECT_FLOAT_EQ(a.distance, float(std::sqrt(best)));
    EXPECT_EQ(a.prim, b.prim);
  }
}

// The views refuse what would let a query read out of range or loop.
TEST(GridViews, RefuseInconsistentLayouts) {
  const Scene scene = scattered(50, 2);
  const FlatGrid g = uniform(scene), n = nested(scene);
  EXPECT_NO_THROW(view_of(g));
  EXPECT_NO_THROW(nested_view_of(n));
  auto uniform_with = [&](auto&& change) {
    FlatGrid bad = g;
    change(bad);
    return view_of(bad);
  };
  auto nested_with = [&](auto&& change) {
    FlatGrid bad = n;
    change(bad);
    return nested_view_of(bad);
  };
  EXPECT_THROW(uniform_with([](FlatGrid& b) { b.offsets[1] = b.offsets.back() + 1; }), BlobError);
  EXPECT_THROW(uniform_with([](FlatGrid& b) { b.refs[0] = 50; }), BlobError);
  EXPECT_THROW(uniform_with([](FlatGrid& b) { b.frame.res[0] = 0; }), BlobError);
  EXPECT_THROW(uniform_with([](FlatGrid& b) { b.frame.res[0] = b.frame.res[1] = 1024; }),
               BlobError);
  EXPECT_THROW(uniform_with([](FlatGrid& b) { b.frame.hi[2] = b.frame.lo[2]; }), BlobError);
  EXPECT_THROW(uniform_with([](FlatGrid& b) { b.frame.lo[1] = NAN; }), BlobError);
  EXPECT_THROW(uniform_with([](FlatGrid& b) { b.offsets.pop_back(); }), BlobError);
  EXPECT_THROW(nested_with([](FlatGrid& b) { b.leaves.back().first_cell += 1; }), BlobError);
  EXPECT_THROW(nested_with([](FlatGrid& b) {
                 for (auto& leaf : b.leaves)
                   if (leaf.res[0] != 0) leaf.res[0] += 1;
               }),
               BlobError);
  EXPECT_THROW(nested_with([](FlatGrid& b) { b.leaves.pop_back(); }), BlobError);
}

}  // namespace
}  // namespace kiln
