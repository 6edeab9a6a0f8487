// The octree against brute force: leaf lists against the exact overlap of every cell, the leaf
// size and depth limits, front-to-back leaf order, degenerate scenes, the surface queries, and
// forged layouts refused by the view. (The ray conformance suite runs the rest.)
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <random>
#include <vector>

#include "kiln/compiler/octree_builder.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/octree.hpp"
#include "kiln/runtime/triangle_geometry.hpp"
#include "proximity_fixtures.hpp"
#include "ray_fixtures.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

using format::Float3;
using namespace kiln::test;

struct Built {
  FlatOctree flat;
  OctreeView view() const {
    return OctreeView(flat.nodes, flat.prim_ids, flat.triangles, flat.bounds);
  }
};

Built build(const Scene& scene, std::uint32_t leaf_size = 8, std::uint32_t max_depth = 16) {
  OctreeBuildOptions o;
  o.leaf_size = leaf_size;
  o.max_depth = max_depth;
  o.threads = 2;
  return {build_octree(scene, o)};
}

// Small triangles scattered in the unit cube, from a fixed seed.
Scene scattered(int count, float size, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::vector<Float3> p;
  std::vector<format::Triangle> t;
  for (int i = 0; i < count; ++i) {
    const Float3 c{unit(rng), unit(rng), unit(rng)};
    add_triangle(p, t, c, {c.x + size * unit(rng), c.y, c.z + size * unit(rng)},
                 {c.x, c.y + size * unit(rng), c.z + size * unit(rng)});
  }
  return make_scene(p, t);
}

// A fan of `count` triangles around one vertex at `centre`.
Scene fan(int count, Float3 centre) {
  std::vector<Float3> p;
  std::vector<format::Triangle> t;
  for (int i = 0; i < count; ++i) {
    const float a0 = 6.2831853f * float(i) / float(count),
                a1 = 6.2831853f * float(i + 1) / float(count);
    const float z = 0.3f * std::sin(3.0f * a0);
    add_triangle(p, t, centre, {centre.x + std::cos(a0), centre.y + std::sin(a0), centre.z + z},
                 {centre.x + std::cos(a1), centre.y + std::sin(a1), centre.z + z});
  }
  return make_scene(p, t);
}

// Every node with its cell and depth, including the cells of absent octants (node = kNoHit).
struct CellEntry {
  std::uint32_t node, depth;
  format::Box3f cell;
};
std::vector<CellEntry> all_cells(const OctreeView& tree) {
  std::vector<CellEntry> out{{0, 0, tree.bounds()}};
  for (std::size_t i = 0; i < out.size(); ++i) {
    const CellEntry e = out[i];
    if (e.node == kNoHit) continue;
    const format::OctreeNode n = tree.nodes()[e.node];
    if (n.is_leaf()) continue;
    std::uint32_t child = n.first_child();
    for (std::uint32_t octant = 0; octant < 8; ++octant)
      out.push_back({(n.child_mask() >> octant & 1u) ? child++ : kNoHit, e.depth + 1,
                     format::octree_child_cell(e.cell, octant)});
  }
  return out;
}

// Every leaf lists exactly the triangles overlapping its cell (the same exact test, done on
// the whole scene), and an absent octant's cell meets no triangle.
void expect_leaf_lists_exact(const Scene& scene, const Built& b) {
  const OctreeView tree = b.view();
  std::size_t leaves = 0, empty = 0;
  for (const CellEntry& e : all_cells(tree)) {
    if (e.node != kNoHit && !tree.nodes()[e.node].is_leaf()) continue;
    const auto expected = brute_box(scene, e.cell.min, e.cell.max);
    if (e.node == kNoHit) {
      ++empty;
      EXPECT_TRUE(expected.empty()) << "an absent octant at depth " << e.depth << " meets "
                                    << expected.size() << " triangles";
      continue;
    }
    ++leaves;
    const format::OctreeNode n = tree.nodes()[e.node];
    const auto refs = tree.prim_ids().subspan(n.first_reference(), n.reference_count());
    EXPECT_EQ(std::vector<std::uint32_t>(refs.begin(), refs.end()), expected)
        << "leaf " << e.node << " at depth " << e.depth;
  }
  EXPECT_EQ(leaves, b.flat.stats.leaf_count);
  EXPECT_EQ(empty, b.flat.stats.empty_cell_count);
}

TEST(Octree, LeafListsAreTheExactOverlapOfEveryCell) {
  expect_leaf_lists_exact(scattered(400, 0.1f, 1), build(scattered(400, 0.1f, 1)));
  const Scene sphere = icosphere(3);
  expect_leaf_lists_exact(sphere, build(sphere, 4));
}

TEST(Octree, RootCellIsTheBoundsMadeCubic) {
  const format::Box3f cell = octree_root_cell({{-1, 2, 3}, {3, 2.5f, 3}});
  EXPECT_EQ(cell.min.x, -1);
  EXPECT_EQ(cell.max.x, 3);
  EXPECT_EQ(cell.min.y, 2);
  EXPECT_EQ(cell.max.y, 6);
  EXPECT_EQ(cell.min.z, 3);
  EXPECT_EQ(cell.max.z, 7);
}

// No leaf deeper than the limit; a leaf over the leaf size only at the limit, or kept whole by
// the no-progress rule (counted apart).
TEST(Octree, LeafSizeAndDepthLimitsAreHonoured) {
  const Scene scene = scattered(3000, 0.02f, 2);
  for (const auto& [leaf_size, max_depth] : {std::pair{1u, 3u}, {4u, 16u}, {16u, 2u}, {64u, 16u}}) {
    SCOPED_TRACE(std::to_string(leaf_size) + " / " + std::to_string(max_depth));
    const Built b = build(scene, leaf_size, max_depth);
    const OctreeView tree = b.view();
    std::uint64_t over_at_limit = 0, over_above_limit = 0;
    for (const CellEntry& e : all_cells(tree)) {
      if (e.node == kNoHit || !tree.nodes()[e.node].is_leaf()) continue;
      EXPECT_LE(e.depth, max_depth);
      if (tree.nodes()[e.node].reference_count() <= leaf_size) continue;
      (e.depth == max_depth ? over_at_limit : over_above_limit) += 1;
    }
    EXPECT_EQ(over_at_limit, b.flat.stats.depth_limited_leaves);
    EXPECT_EQ(over_above_limit, b.flat.stats.stalled_leaves);
    EXPECT_EQ(over_above_limit, 0u);  // small scattered triangles always separate
    EXPECT_LE(tree.depth(), max_depth);
  }
}

// The leaves a ray meets come front to back (entry distances non-decreasing, up to the
// rounding padding), and include every leaf whose cell a double-precision slab test says the ray
// crosses (entering it before it leaves).
TEST(Octree, LeavesAlongARayComeFrontToBackAndMissNone) {
  const Scene scene = scattered(1500, 0.05f, 3);
  const Built b = build(scene, 4);
  const OctreeView tree = b.view();
  std::vector<std::pair<std::uint32_t, format::Box3f>> leaves;
  for_each_octree_leaf(tree, [&](const format::OctreeNode& n, const format::Box3f& cell) {
    leaves.push_back({std::uint32_t(&n - tree.nodes().data()), cell});
  });
  std::size_t checked = 0;
  for (const Ray& ray : box_rays(scene, 400)) {
    std::vector<std::uint32_t> seen;
    float last = -INFINITY;
    octree_leaves_along(tree, ray, [&](std::uint32_t node, float entry, float exit) {
      EXPECT_GE(entry, last - 1e-5f * std::fabs(last)) << "leaf " << node;
      EXPECT_LE(entry, exit * (1 + 1e-5f) + 1e-30f);
      last = std::max(last, entry);
      seen.push_back(node);
    });
    std::sort(seen.begin(), seen.end());
    EXPECT_EQ(std::adjacent_find(seen.begin(), seen.end()), seen.end()) << "a leaf met twice";
    for (const auto& [node, cell] : leaves) {
      double t0 = ray.tmin, t1 = ray.tmax;
      for (int a = 0; a < 3; ++a) {
        const double o = format::at(ray.org, a), d = format::at(ray.dir, a);
        const double lo = format::at(cell.min, a), hi = format::at(cell.max, a);
        if (d == 0) {
          if (o < lo || o > hi) t0 = INFINITY;
          continue;
        }
        const double ta = (lo - o) / d, tb = (hi - o) / d;
        t0 = std::max(t0, std::min(ta, tb)), t1 = std::min(t1, std::max(ta, tb));
      }
      // Cells crossed over a clear length: a grazing touch is rounding's to decide.
      if (t1 - t0 <= 1e-6 * (1 + std::fabs(t0))) continue;
      ++checked;
      EXPECT_TRUE(std::binary_search(seen.begin(), seen.end(), node)) << "leaf " << node;
    }
  }
  EXPECT_GT(checked, 1000u);
}

// Scenes that break naive subdivision: rays still agree with brute force and references stay
// bounded.
TEST(Octree, DegenerateScenes) {
  std::vector<std::pair<std::string, Scene>> scenes;
  {  // every triangle in one plane
    std::vector<Float3> p;
    std::vector<format::Triangle> t;
    for (int i = 0; i < 20; ++i)
      for (int j = 0; j < 20; ++j) {
        const float x = float(i) / 20, y = float(j) / 20, s = 1.0f / 20;
        add_triangle(p, t, {x, y, 0.5f}, {x + s, y, 0.5f}, {x + s, y + s, 0.5f});
        add_triangle(p, t, {x, y, 0.5f}, {x + s, y + s, 0.5f}, {x, y + s, 0.5f});
      }
    scenes.emplace_back("plane", make_scene(p, t));
  }
  {
    std::vector<Float3> p;
    std::vector<format::Triangle> t;
    add_triangle(p, t, {0, 0, 0}, {1, 0, 0}, {0, 1, 0.5f});
    scenes.emplace_back("one triangle", make_scene(p, t));
  }
  scenes.emplace_back("fan", fan(600, {0.1f, 0.2f, 0.3f}));
  // The shared vertex on the root cell's centre: it lies in all eight children.
  scenes.emplace_back("fan at the centre", fan(600, {0, 0, 0}));
  for (const auto& [name, scene] : scenes) {
    SCOPED_TRACE(name);
    const Built b = build(scene);
    expect_agrees_with_brute_force(scene, b.view(), box_rays(scene, 1500));
    EXPECT_LT(b.flat.stats.references_per_triangle, 12.0);
    EXPECT_LE(b.flat.stats.max_depth, 16u);
  }
}

TEST(Octree, AgreesWithBruteForceWithTinyLeavesAndShallowTrees) {
  for (const auto& [name, scene] : worst_cases()) {
    SCOPED_TRACE(name);
    for (const auto& [leaf_size, max_depth] : {std::pair{1u, 8u}, {32u, 3u}})
      expect_agrees_with_brute_force(scene, build(scene, leaf_size, max_depth).view(),
                                     box_rays(scene, 400));
  }
}

// Large triangles crossing each other everywhere double their references at every level: the
// budget stops the descent there, and rays still agree with brute force.
TEST(Octree, ReferenceBudgetBoundsReferences) {
  const Scene scene = worst_cases().at("overlapping");
  for (const std::uint32_t budget : {2u, 6u, 32u}) {
    SCOPED_TRACE(budget);
    OctreeBuildOptions o;
    o.reference_budget = budget;
    o.threads = 2;
    const Built b{build_octree(scene, o)};
    EXPECT_LE(b.flat.stats.reference_count, std::uint64_t(budget) * scene.triangles.size());
    EXPECT_TRUE(b.flat.stats.budget_reached);
    expect_agrees_with_brute_force(scene, b.view(), box_rays(scene, 300));
  }
  EXPECT_FALSE(build(scattered(2000, 0.02f, 4)).flat.stats.budget_reached);
}

TEST(Octree, SurfaceQueriesMatchBruteForce) {
  auto scenes = worst_cases();
  scenes.emplace("sphere", icosphere(3));
  for (const auto& [name, scene] : scenes) {
    SCOPED_TRACE(name);
    const Built b = build(scene);
    const OctreeView tree = b.view();
    for (const Float3& p : sample_points(scene, 300, 5)) {
      const double expected = brute_closest(scene, p);
      const ClosestPoint got = closest_point(tree, p);
      ASSERT_NE(got.prim, kNoHit);
      EXPECT_NEAR(got.distance, expected, 1e-6 * expected + 1e-30);
    }
    std::vector<std::uint32_t> got;
    for (const QueryBox& box : query_boxes(scene, 60, 4)) {
      triangles_in_box(tree, box.lo, box.hi, got);
      EXPECT_EQ(got, brute_box(scene, box.lo, box.hi));
    }
  }
  const Scene sphere = icosphere(3);
  const Built b = build(sphere);
  std::size_t inside = 0;
  for (const Float3& p : sample_points(sphere, 1000, 11)) {
    const bool expected = winding_number(sphere, p) > 0.5;
    inside += expected;
    EXPECT_EQ(point_inside(b.view(), p), expected);
  }
  EXPECT_GT(inside, 100u);
}

// Hand-made layouts the view must refuse.
TEST(Octree, ViewRefusesForgedLayouts) {
  const std::vector<format::RayTriangle> tris{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
  using N = format::OctreeNode;
  auto refused = [&](std::vector<N> nodes, std::vector<std::uint32_t> ids,
                     format::Box3f bounds = {{0, 0, 0}, {1, 1, 1}}) {
    try {
      OctreeView(nodes, ids, tris, bounds);
    } catch (const BlobError&) {
      return true;
    }
    return false;
  };
  EXPECT_FALSE(refused({N::leaf(0, 1)}, {0}));
  EXPECT_FALSE(refused({N::interior(0x81, 1), N::leaf(0, 1), N::leaf(1, 0)}, {0}));
  EXPECT_TRUE(refused({}, {}));
  EXPECT_TRUE(refused({N::interior(1, 0)}, {}));                  // its own child
  EXPECT_TRUE(refused({N::interior(3, 1), N::leaf(0, 1)}, {0}));  // child out of range
  EXPECT_TRUE(refused({N::interior(1, 2), N::leaf(0, 1), N::leaf(1, 0)}, {0}));  // gap
  EXPECT_TRUE(refused({N::leaf(0, 2)}, {0}));                      // references beyond
  EXPECT_TRUE(refused({N::leaf(0, 1)}, {0, 0}));                   // a reference in no leaf
  EXPECT_TRUE(refused({N::leaf(0, 1)}, {1}));                      // no such triangle
  EXPECT_TRUE(refused({N{1, 1u << 8 | 1u}, N::leaf(0, 1)}, {0}));  // reserved bits
  EXPECT_TRUE(refused({N::leaf(0, 1)}, {0}, {{0, 0, 0}, {NAN, 1, 1}}));
  EXPECT_TRUE(refused({N::leaf(0, 1)}, {0}, {{0, 0, 0}, {0, 1, 1}}));
  // A chain one level deeper than kOctreeMaxDepth.
  std::vector<N> chain;
  for (std::uint32_t i = 0; i <= format::kOctreeMaxDepth; ++i)
    chain.push_back(N::interior(1, i + 1));
  chain.push_back(N::leaf(0, 1));
  EXPECT_TRUE(refused(chain, {0}));
  chain.erase(chain.begin());
  for (std::uint32_t i = 0; i + 1 < chain.size(); ++i) chain[i] = N::interior(1, i + 1);
  EXPECT_FALSE(refused(chain, {0}));
}

}  // namespace
}  // namespace kiln
