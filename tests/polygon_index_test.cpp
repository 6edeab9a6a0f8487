// The polygon index and the exact 2D predicates: orient2d against exact integer arithmetic,
// the half-open boundary rule on hand-made shapes and on a partition, every answer against a
// brute-force crossing-number scan (written here, independently of the index) on the shared
// county, state and country layers, ZIP points against the counties, determinism and forged
// bytes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <random>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "kiln/compiler/csv_reader.hpp"
#include "kiln/compiler/geo_import.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/compiler/polygon_index_builder.hpp"
#include "kiln/compiler/scene.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/polygon_index.hpp"
#include "kiln/runtime/predicates2.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

using format::Box2d;
using format::Double2;

// The shared data beside the project (as in CI), whatever directory the test runs in.
const std::string kGeo = KILN_MESH_DIR "/../geo/";

// ---- exact references ----------------------------------------------------------------------

// The sign of orient2d on doubles that are all multiples of 2^-shift with |value| * 2^shift
// < 2^53: scaled to integers, the determinant is exact in 128 bits.
int exact_orient_sign(Double2 a, Double2 b, Double2 c, int shift) {
  auto i = [shift](double v) { return __int128(std::ldexp(v, shift)); };
  const __int128 det =
      (i(a.x) - i(c.x)) * (i(b.y) - i(c.y)) - (i(a.y) - i(c.y)) * (i(b.x) - i(c.x));
  return det > 0 ? 1 : det < 0 ? -1 : 0;
}

int sign(double v) {
  return v > 0 ? 1 : v < 0 ? -1 : 0;
}

// Points on or a few ulps off the line through a and b, in [lo, 2 lo) (shift makes them exact).
void check_near_line(double lo, int shift, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(lo, 2 * lo), t(0.0, 1.0);
  int zero = 0, nonzero = 0;
  for (int i = 0; i < 20000; ++i) {
    const Double2 a{u(rng), u(rng)}, b{u(rng), u(rng)};
    const double s = t(rng);
    Double2 c{a.x + s * (b.x - a.x), a.y + s * (b.y - a.y)};
    for (int k = int(rng() % 4); k-- > 0;) c.x = std::nextafter(c.x, (rng() & 1) ? 0.0 : 4 * lo);
    if (!(c.x >= lo && c.x < 2 * lo && c.y >= lo && c.y < 2 * lo)) continue;
    const int want = exact_orient_sign(a, b, c, shift);
    ASSERT_EQ(sign(orient2d(a, b, c)), want) << i;
    ASSERT_EQ(sign(orient2d(b, c, a)), want) << i;  // cyclic permutations agree
    ASSERT_EQ(sign(orient2d(b, a, c)), -want) << i;
    (want == 0 ? zero : nonzero)++;
  }
  EXPECT_GT(nonzero, 1000);
}

TEST(Predicates2, Orient2dMatchesExactArithmeticNearTheLine) {
  check_near_line(0x1p20, 32, 1);  // ulp 2^-32: integers below 2^53 after scaling
  check_near_line(64.0, 46, 2);    // longitudes: ulp 2^-46
}

TEST(Predicates2, Orient2dExactOnCollinearAndTinyTurns) {
  // Exactly collinear points whose naive determinant rounds to non-zero, and turns of one ulp.
  const Double2 a{0.5, 0.5}, b{12.0, 12.0}, c{24.0, 24.0};
  EXPECT_EQ(orient2d(a, b, c), 0.0);
  for (int k = 0; k < 64; ++k) {
    const Double2 p{0.5 + std::ldexp(1.0, -k % 50), 0.5 + std::ldexp(1.0, -k % 50)};
    const Double2 up{p.x, std::nextafter(p.y, 1e9)}, down{p.x, std::nextafter(p.y, -1e9)};
    EXPECT_EQ(orient2d(b, c, p), 0.0) << k;
    EXPECT_GT(orient2d(b, c, up), 0.0) << k;
    EXPECT_LT(orient2d(b, c, down), 0.0) << k;
  }
  // Shewchuk's classic failure of the naive test: a tiny grid near (0.5, 0.5).
  for (int i = 0; i < 64; ++i)
    for (int j = 0; j < 64; ++j) {
      const Double2 p{0.5 + i * 0x1p-53, 0.5 + j * 0x1p-53};
      const Double2 q{12.0, 12.0}, r{24.0, 24.0};
      const int want = exact_orient_sign(p, q, r, 53);
      ASSERT_EQ(sign(orient2d(p, q, r)), want) << i << "," << j;
    }
}

// ---- layers ---------------------------------------------------------------------------------

// A layer builder for hand-made shapes: each feature a list of polygons, each a list of rings.
using Ring = std::vector<Double2>;
using Poly = std::vector<Ring>;

PolygonLayer make_layer(const std::vector<std::vector<Poly>>& features) {
  PolygonLayer layer;
  for (const auto& f : features) {
    for (const Poly& poly : f) {
      for (const Ring& ring : poly) {
        for (const Double2& v : ring) layer.vertices.push_back(v), layer.bounds.grow(v);
        layer.ring_vertices.push_back(layer.vertices.size());
      }
      layer.polygon_rings.push_back(layer.ring_vertices.size() - 1);
    }
    layer.feature_polygons.push_back(layer.polygon_rings.size() - 1);
    layer.ids.push(std::to_string(layer.ids.size()));
    layer.names.push(std::string("f").append(std::to_string(layer.names.size())));
  }
  return layer;
}

// Kiln's GeoJSON reader, dropping broken features (the shared states file has one ring that is
// not closed: feature 19, Illinois), which stay as empty features.
PolygonLayer load_layer(const std::string& path) {
  GeoImportOptions options;
  options.skip_invalid = true;
  return *import_geo_file(path, options).polygons;
}

bool have_shared() {
  return std::filesystem::exists(kGeo + "MANIFEST.md");
}

// ---- brute force ----------------------------------------------------------------------------

// Crossing number over every ring of a polygon: the edge spans p.y half-open and lies strictly
// to the right of p (checked with the exact orientation of the upward-directed edge).
bool crosses(Double2 a, Double2 b, const Double2& p) {
  if (a.y > b.y) std::swap(a, b);
  return a.y <= p.y && p.y < b.y && orient2d(a, b, p) > 0;
}

bool brute_polygon_contains(const PolygonLayer& layer, std::size_t polygon, const Double2& p) {
  int crossings = 0;
  for (auto r = layer.polygon_rings[polygon]; r < layer.polygon_rings[polygon + 1]; ++r) {
    const auto lo = layer.ring_vertices[r], hi = layer.ring_vertices[r + 1];
    for (auto i = lo; i < hi; ++i)
      crossings += crosses(layer.vertices[i], layer.vertices[i + 1 == hi ? lo : i + 1], p);
  }
  return crossings % 2 == 1;
}

// The same scan over every polygon, with each polygon's edges bucketed into horizontal bands of
// its bounding box so that a point tests only the edges whose y-range may hold it (an edge sits
// in every band it overlaps): the crossing number itself is unchanged.
struct BruteForce {
  static constexpr int kBands = 64;
  const PolygonLayer& layer;
  std::vector<Box2d> boxes;
  std::vector<std::vector<std::pair<Double2, Double2>>> bands;  // polygon * kBands + band

  explicit BruteForce(const PolygonLayer& l)
      : layer(l), boxes(l.polygon_count()), bands(l.polygon_count() * kBands) {
    for (std::size_t q = 0; q < l.polygon_count(); ++q) {
      for (auto i = l.ring_vertices[l.polygon_rings[q]];
           i < l.ring_vertices[l.polygon_rings[q + 1]]; ++i)
        boxes[q].grow(l.vertices[i]);
      for (auto r = l.polygon_rings[q]; r < l.polygon_rings[q + 1]; ++r) {
        const auto lo = l.ring_vertices[r], hi = l.ring_vertices[r + 1];
        for (auto i = lo; i < hi; ++i) {
          const Double2 a = l.vertices[i], b = l.vertices[i + 1 == hi ? lo : i + 1];
          for (int k = band(q, std::min(a.y, b.y)); k <= band(q, std::max(a.y, b.y)); ++k)
            bands[q * kBands + k].push_back({a, b});
        }
      }
    }
  }
  int band(std::size_t q, double y) const {
    const double h = boxes[q].max.y - boxes[q].min.y;
    const int k = h > 0 ? int((y - boxes[q].min.y) / h * kBands) : 0;
    return std::clamp(k, 0, kBands - 1);
  }
  bool contains(std::size_t q, const Double2& p) const {
    if (!boxes[q].contains(p)) return false;
    int crossings = 0;
    for (const auto& [a, b] : bands[q * kBands + band(q, p.y)]) crossings += crosses(a, b, p);
    return crossings % 2 == 1;
  }
  std::vector<std::uint32_t> all(const Double2& p) const {
    std::vector<std::uint32_t> out;
    for (std::size_t f = 0; f < layer.feature_count(); ++f)
      for (auto q = layer.feature_polygons[f]; q < layer.feature_polygons[f + 1]; ++q)
        if (contains(q, p)) {
          out.push_back(std::uint32_t(f));
          break;
        }
    return out;
  }
};

PolygonIndexView open_view(const PolygonLayer& layer, const FlatPolygonIndex& index) {
  return PolygonIndexView({view_of(layer), index.bounds, index.nodes, index.entries, index.edges});
}

// The leaf-record kernels this CPU runs (KILN_POLYGON_KERNEL names them).
std::vector<const char*> record_kernels() {
  std::vector<const char*> out{"scalar"};
#if defined(__x86_64__) || defined(__i386__)
  out.push_back("sse2");
  if (__builtin_cpu_supports("avx2")) out.push_back("avx2");
#endif
  return out;
}

// A view of the same parts whose leaf records answer through `kernel`.
PolygonIndexView view_with_kernel(const PolygonIndexView& view, const char* kernel) {
  setenv("KILN_POLYGON_KERNEL", kernel, 1);
  PolygonIndexView out(view.parts());
  unsetenv("KILN_POLYGON_KERNEL");
  return out;
}

// Brute force against locate_all (a descent from the root over the stored entries), and against
// locate and locate_many (the table, branches and leaf records derived at open) with every
// record kernel.
void expect_agrees(const PolygonLayer& layer, const PolygonIndexView& view,
                   const std::vector<Double2>& points, const char* what) {
  const BruteForce brute(layer);
  std::vector<std::uint32_t> got, first(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto want = brute.all(points[i]);
    view.locate_all(points[i], got);
    ASSERT_EQ(got, want) << what << " point " << i << " (" << points[i].x << ", " << points[i].y
                         << ")";
    first[i] = want.empty() ? PolygonQueries::kNone : want[0];
  }
  for (const char* kernel : record_kernels()) {
    const PolygonIndexView v = view_with_kernel(view, kernel);
    for (std::size_t i = 0; i < points.size(); ++i)
      ASSERT_EQ(v.locate(points[i]), first[i]) << what << " kernel " << kernel << " point " << i
                                               << " (" << points[i].x << ", " << points[i].y << ")";
    // The batch call (groups of points through each stage together) answers as locate does.
    std::vector<std::uint32_t> many(points.size() + 1, 12345);
    v.locate_many(points, std::span(many).first(points.size()));
    for (std::size_t i = 0; i < points.size(); ++i)
      ASSERT_EQ(many[i], first[i]) << what << " kernel " << kernel << " batch point " << i;
    EXPECT_EQ(many.back(), 12345u);  // nothing written past `out`
  }
}

// The centre of every leaf (where the records' segments start) and its corners.
std::vector<Double2> cell_points(const PolygonIndexView& view) {
  std::vector<IndexCell2> cells;
  view.cells(cells);
  std::vector<Double2> points;
  for (const IndexCell2& c : cells) {
    points.push_back(format::quadtree_centre(c.box));
    points.push_back(c.box.min);
    points.push_back(c.box.max);
  }
  return points;
}

// Every vertex, every edge's midpoint and points a few ulps around vertices.
std::vector<Double2> boundary_points(const PolygonLayer& layer, std::size_t stride) {
  std::vector<Double2> points;
  for (std::size_t r = 0; r < layer.ring_count(); ++r) {
    const auto lo = layer.ring_vertices[r], hi = layer.ring_vertices[r + 1];
    for (auto i = lo; i < hi; i += stride) {
      const Double2 a = layer.vertices[i], b = layer.vertices[i + 1 == hi ? lo : i + 1];
      points.push_back(a);
      points.push_back({0.5 * a.x + 0.5 * b.x, 0.5 * a.y + 0.5 * b.y});
      points.push_back({std::nextafter(a.x, 1e9), a.y});
      points.push_back({a.x, std::nextafter(a.y, -1e9)});
    }
  }
  return points;
}

std::vector<Double2> random_points(const Box2d& box, std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> x(box.min.x, box.max.x), y(box.min.y, box.max.y);
  std::vector<Double2> points(n);
  for (auto& p : points) p = {x(rng), y(rng)};
  return points;
}

// ---- hand-made shapes -----------------------------------------------------------------------

// A square with a square hole; two squares sharing an edge (one clockwise); a multipolygon of two
// triangles meeting at a vertex; a square overlapping the first (two answers for --all).
PolygonLayer shapes() {
  const Ring outer{{0, 0}, {10, 0}, {10, 10}, {0, 10}}, hole{{3, 3}, {3, 7}, {7, 7}, {7, 3}};
  const Ring left{{10, 0}, {20, 0}, {20, 10}, {10, 10}};
  const Ring right{{20, 0}, {20, 10}, {30, 10}, {30, 0}};
  const Ring t1{{0, 20}, {5, 20}, {5, 25}}, t2{{5, 25}, {10, 25}, {10, 30}};
  const Ring overlap{{8, 8}, {12, 8}, {12, 12}, {8, 12}};
  return make_layer({{{outer, hole}}, {{left}}, {{right}}, {{t1}, {t2}}, {{overlap}}});
}

TEST(PolygonIndex, HandMadeShapesAgreeWithBruteForceOnBoundaries) {
  const PolygonLayer layer = shapes();
  for (const std::uint32_t max_edges : {1u, 4u, 64u}) {
    const FlatPolygonIndex index = build_polygon_index(view_of(layer), {max_edges, 8, 1});
    const PolygonIndexView view = open_view(layer, index);
    auto points = boundary_points(layer, 1);
    const auto more = random_points(layer.bounds, 2000, max_edges);
    points.insert(points.end(), more.begin(), more.end());
    for (double x = -1; x <= 31; x += 0.5)
      for (double y = -1; y <= 31; y += 0.5) points.push_back({x, y});
    const auto cells = cell_points(view);
    points.insert(points.end(), cells.begin(), cells.end());
    expect_agrees(layer, view, points, "shapes");
  }
  const FlatPolygonIndex index = build_polygon_index(view_of(layer), {4, 8, 1});
  const PolygonIndexView view = open_view(layer, index);
  EXPECT_EQ(view.locate({5, 5}), PolygonQueries::kNone);  // in the hole
  EXPECT_EQ(view.locate({1, 1}), 0u);
  EXPECT_EQ(view.locate({3, 5}), PolygonQueries::kNone);  // hole's left edge: hole side (right)
  EXPECT_EQ(view.locate({7, 5}), 0u);                     // hole's right edge: outer side
  EXPECT_EQ(view.locate({10, 5}), 1u);                    // the shared edge goes right
  EXPECT_EQ(view.locate({20, 5}), 2u);
  EXPECT_EQ(view.locate({4, 21}), 3u);  // the lower triangle of the multipolygon
  std::vector<std::uint32_t> all;
  view.locate_all({9, 9}, all);
  EXPECT_EQ(all, (std::vector<std::uint32_t>{0, 4}));
  EXPECT_EQ(view.locate({9, 9}), 0u);  // the lowest feature index
  EXPECT_EQ(view.locate({-1, 5}), PolygonQueries::kNone);
  EXPECT_EQ(view.locate({std::nan(""), 5}), PolygonQueries::kNone);
}

// Points on the top-level table's split lines and one ulp either side, and at their crossings:
// the lookup (and the cells it answers without a descent) agrees with brute force there, on a
// tree deep enough for a table of several levels.
TEST(PolygonIndex, PointsOnTheTopTableSplitLinesAgreeWithBruteForce) {
  const PolygonLayer layer = shapes();
  const FlatPolygonIndex index = build_polygon_index(view_of(layer), {1, 10, 1});
  const PolygonIndexView view = open_view(layer, index);
  const auto grid = make_polygon_index_top_grid(view.parts());
  ASSERT_GE(grid->level, 3u);
  std::vector<Double2> points;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> x(layer.bounds.min.x, layer.bounds.max.x),
      y(layer.bounds.min.y, layer.bounds.max.y);
  for (std::size_t i = 0; i < grid->xs.size(); ++i)
    for (const double line :
         {grid->xs[i], std::nextafter(grid->xs[i], -1e9), std::nextafter(grid->xs[i], 1e9)}) {
      points.push_back({line, y(rng)});
      points.push_back({line, grid->ys[i]});
    }
  for (std::size_t i = 0; i < grid->ys.size(); ++i)
    for (const double line :
         {grid->ys[i], std::nextafter(grid->ys[i], -1e9), std::nextafter(grid->ys[i], 1e9)})
      points.push_back({x(rng), line});
  expect_agrees(layer, view, points, "split lines");
}

// A clear bit is set exactly where the table cell and its eight neighbours (those inside the
// table) code "none", on tables of 2^1 to 2^9 cells a side.
TEST(PolygonIndex, ClearBitsMarkCellsWithEmptyNeighbourhoods) {
  const PolygonLayer layer = shapes();
  std::vector<std::uint32_t> levels;
  for (const std::uint32_t max_edges : {64u, 16u, 4u, 1u}) {
    const FlatPolygonIndex index = build_polygon_index(view_of(layer), {max_edges, 12, 1});
    const PolygonIndexView view = open_view(layer, index);
    const auto g = make_polygon_index_top_grid(view.parts());
    levels.push_back(g->level);
    const std::size_t side = std::size_t(1) << g->level;
    auto none = [&](std::size_t x, std::size_t y) {
      return x >= side || y >= side ||
             g->code[y * side + x] ==
                 (PolygonIndexTopGrid::kAnswer | PolygonIndexTopGrid::kNoFeature);
    };
    for (std::size_t y = 0; y < side; ++y)
      for (std::size_t x = 0; x < side; ++x) {
        bool want = true;
        for (std::size_t dy = 0; dy < 3; ++dy)
          for (std::size_t dx = 0; dx < 3; ++dx) want &= none(x + dx - 1, y + dy - 1);
        const std::size_t cell = y * side + x;
        ASSERT_EQ(bool(g->clear[cell / 64] >> (cell % 64) & 1), want)
            << g->level << " " << x << "," << y;
      }
  }
  EXPECT_LT(*std::min_element(levels.begin(), levels.end()), 6u);  // rows narrower than a word
  EXPECT_GE(*std::max_element(levels.begin(), levels.end()), 7u);  // rows of whole words
}

// Forty concentric squares: leaves crossing their sides list up to forty polygons, so their
// records hold two groups (31 polygons each at most), and a point outside the 31 smallest is
// answered by the second.
TEST(PolygonIndex, LeavesOfManyPolygonsAgreeWithBruteForce) {
  std::vector<std::vector<Poly>> features;
  for (int i = 0; i < 40; ++i) {
    const double r = 1 + 0.25 * i;
    features.push_back(
        {{{{50 - r, 50 - r}, {50 + r, 50 - r}, {50 + r, 50 + r}, {50 - r, 50 + r}}}});
  }
  const PolygonLayer layer = make_layer(features);
  const FlatPolygonIndex index = build_polygon_index(view_of(layer), {8, 3, 1});
  std::uint32_t most = 0;
  for (const auto& n : index.nodes)
    if (n.is_leaf()) most = std::max(most, n.count);
  ASSERT_GT(most, 31u);
  const PolygonIndexView view = open_view(layer, index);
  auto points = boundary_points(layer, 1);
  const auto more = random_points(layer.bounds, 5000, 21), cells = cell_points(view);
  points.insert(points.end(), more.begin(), more.end());
  points.insert(points.end(), cells.begin(), cells.end());
  expect_agrees(layer, view, points, "concentric");
  EXPECT_EQ(view.locate({50 + 1 + 0.25 * 35 - 0.1, 50}), 35u);  // in the second group only
}

// Edges a record lists twice: a zero-width spike (out and back along the same edge), a hole
// sharing an edge with its outer ring, and neighbours sharing edges drawn in either direction.
// Their crossings cancel or flip both polygons, as the crossing number does.
TEST(PolygonIndex, RepeatedEdgesAgreeWithBruteForce) {
  const Ring spiked{{0, 0}, {10, 0}, {10, 5}, {16, 5}, {10, 5}, {10, 10}, {0, 10}};
  const Ring outer{{20, 0}, {30, 0}, {30, 10}, {20, 10}}, hole{{20, 2}, {24, 2}, {24, 6}, {20, 6}};
  const Ring left{{0, 20}, {10, 20}, {10, 30}, {0, 30}};
  const Ring right_cw{{10, 20}, {10, 30}, {20, 30}, {20, 20}};
  const Ring below{{0, 12}, {10, 12}, {10, 20}, {0, 20}};
  const PolygonLayer layer =
      make_layer({{{spiked}}, {{outer, hole}}, {{left}}, {{right_cw}}, {{below}}});
  for (const std::uint32_t max_edges : {1u, 3u, 64u}) {
    const FlatPolygonIndex index = build_polygon_index(view_of(layer), {max_edges, 8, 1});
    const PolygonIndexView view = open_view(layer, index);
    auto points = boundary_points(layer, 1);
    const auto more = random_points(layer.bounds, 3000, 5), cells = cell_points(view);
    points.insert(points.end(), more.begin(), more.end());
    points.insert(points.end(), cells.begin(), cells.end());
    for (double x = -1; x <= 31; x += 0.25)
      for (double y = -1; y <= 31; y += 0.25) points.push_back({x, y});
    expect_agrees(layer, view, points, "repeated edges");
  }
}

// Bounds a few hundred ulps wide at large coordinates: the split lines of the table collapse
// onto each other, the uniform estimate of a column is far from the true one, and the table's
// clear bits stay unset; answers stay exact.
TEST(PolygonIndex, TinyBoundsAtLargeCoordinatesAgreeWithBruteForce) {
  const double o = 1e6, u = std::nextafter(o, 2e6) - o;  // one ulp at 1e6
  std::vector<std::vector<Poly>> features;
  std::mt19937_64 rng(9);
  std::uniform_int_distribution<int> step(0, 300);
  for (int i = 0; i < 30; ++i) {
    const Double2 a{o + step(rng) * u, o + step(rng) * u}, b{o + step(rng) * u, o + step(rng) * u};
    const Double2 c{o + step(rng) * u, o + step(rng) * u};
    features.push_back({{{a, b, c}}});
  }
  const PolygonLayer layer = make_layer(features);
  const FlatPolygonIndex index = build_polygon_index(view_of(layer), {1, 10, 1});
  const PolygonIndexView view = open_view(layer, index);
  const auto grid = make_polygon_index_top_grid(view.parts());
  ASSERT_GE(grid->level + PolygonIndexTopGrid::kFine, 9u);  // 2^9 fine columns over 300 ulps
  EXPECT_TRUE(std::all_of(grid->clear.begin(), grid->clear.end(), [](auto w) { return w == 0; }));
  std::vector<Double2> points = boundary_points(layer, 1);
  for (int y = -2; y <= 302; ++y)
    for (int x = -2; x <= 302; x += 3) points.push_back({o + x * u, o + y * u});
  const auto cells = cell_points(view);
  points.insert(points.end(), cells.begin(), cells.end());
  expect_agrees(layer, view, points, "tiny bounds");
}

// locate_many over every batch size up to a few pipeline groups answers as locate does and
// writes nothing past its output; a shorter output answers as many points as it holds.
TEST(PolygonIndex, BatchesOfEverySizeAnswerAsSingleCalls) {
  const PolygonLayer layer = shapes();
  const FlatPolygonIndex index = build_polygon_index(view_of(layer), {1, 10, 1});
  const PolygonIndexView view = open_view(layer, index);
  Box2d wide = layer.bounds;
  wide.min = {wide.min.x - 2, wide.min.y - 2};
  wide.max = {wide.max.x + 2, wide.max.y + 2};
  auto points = random_points(wide, 100, 8);
  const auto edges = boundary_points(layer, 3);
  points.insert(points.begin() + 50, edges.begin(), edges.begin() + 20);
  for (const char* kernel : record_kernels()) {
    const PolygonIndexView v = view_with_kernel(view, kernel);
    for (std::size_t n = 0; n <= 100; ++n) {
      std::vector<std::uint32_t> many(n + 1, 12345);
      v.locate_many(std::span(points).first(n), std::span(many).first(n));
      for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(many[i], v.locate(points[i])) << n << " " << i;
      ASSERT_EQ(many[n], 12345u) << n;
    }
    std::vector<std::uint32_t> shorter(31, 12345);
    v.locate_many(points, std::span(shorter).first(30));
    for (std::size_t i = 0; i < 30; ++i) EXPECT_EQ(shorter[i], v.locate(points[i]));
    EXPECT_EQ(shorter[30], 12345u);
  }
}

// A partition of [0, n]^2 into jittered quads split along alternating diagonals into triangles
// (every polygon shares its borders vertex for vertex): every point is in at most one polygon,
// and in exactly one when inside the union's interior.
TEST(PolygonIndex, PartitionPointsFallInExactlyOnePolygon) {
  const int n = 12;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  std::vector<Double2> grid((n + 1) * (n + 1));
  for (int y = 0; y <= n; ++y)
    for (int x = 0; x <= n; ++x) {
      const bool edge = x == 0 || y == 0 || x == n || y == n;
      grid[y * (n + 1) + x] = {x + (edge ? 0 : jitter(rng)), y + (edge ? 0 : jitter(rng))};
    }
  std::vector<std::vector<Poly>> features;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const Double2 a = grid[y * (n + 1) + x], b = grid[y * (n + 1) + x + 1];
      const Double2 c = grid[(y + 1) * (n + 1) + x + 1], d = grid[(y + 1) * (n + 1) + x];
      if ((x + y) % 3 == 0) {
        features.push_back({{{a, b, c, d}}});  // a quad
      } else if ((x + y) % 2) {
        features.push_back({{{a, b, c}}});
        features.push_back({{{a, c, d}}});
      } else {
        features.push_back({{{a, b, d}}});
        features.push_back({{{b, c, d}}});
      }
    }
  const PolygonLayer layer = make_layer(features);
  const FlatPolygonIndex index = build_polygon_index(view_of(layer), {6, 10, 2});
  const PolygonIndexView view = open_view(layer, index);
  auto points = boundary_points(layer, 1);
  const auto more = random_points(layer.bounds, 5000, 3), cells = cell_points(view);
  points.insert(points.end(), more.begin(), more.end());
  points.insert(points.end(), cells.begin(), cells.end());
  expect_agrees(layer, view, points, "partition");
  std::vector<std::uint32_t> all;
  for (const Double2& p : points) {
    view.locate_all(p, all);
    EXPECT_LE(all.size(), 1u);
    const bool interior = p.x >= 0 && p.x < n && p.y >= 0 && p.y < n;  // the rule's half-open box
    EXPECT_EQ(all.size(), interior ? 1u : 0u) << p.x << "," << p.y;
  }
}

TEST(PolygonIndex, FeaturesInBoxMatchBruteForce) {
  const PolygonLayer layer = shapes();
  const FlatPolygonIndex index = build_polygon_index(view_of(layer), {2, 8, 1});
  const PolygonIndexView view = open_view(layer, index);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-2, 32), s(0, 6);
  std::vector<std::uint32_t> got;
  for (int i = 0; i < 3000; ++i) {
    Box2d box;
    box.min = {u(rng), u(rng)};
    box.max = {box.min.x + (i % 5 ? s(rng) : 0), box.min.y + (i % 7 ? s(rng) : 0)};
    if (i % 11 == 0) box.min = box.max = {std::round(box.min.x), std::round(box.min.y)};
    // Brute force: an edge meets the box, or a box point lies inside (then all of it does).
    std::vector<std::uint32_t> want;
    for (std::size_t f = 0; f < layer.feature_count(); ++f) {
      bool meets = false;
      for (auto q = layer.feature_polygons[f]; q < layer.feature_polygons[f + 1] && !meets; ++q) {
        for (auto r = layer.polygon_rings[q]; r < layer.polygon_rings[q + 1]; ++r) {
          const auto lo = layer.ring_vertices[r], hi = layer.ring_vertices[r + 1];
          for (auto k = lo; k < hi; ++k)
            meets = meets ||
                    segment_meets_box(layer.vertices[k], layer.vertices[k + 1 == hi ? lo : k + 1],
                                      box.min, box.max);
        }
        meets = meets || brute_polygon_contains(layer, q, box.min);
      }
      if (meets) want.push_back(std::uint32_t(f));
    }
    view.features_in_box(box, got);
    ASSERT_EQ(got, want) << i;
  }
}

// ---- the shared layers ----------------------------------------------------------------------

class SharedLayers : public ::testing::TestWithParam<const char*> {};

TEST_P(SharedLayers, RandomAndBoundaryPointsAgreeWithBruteForce) {
  if (!have_shared()) GTEST_SKIP() << "../shared/data/geo is absent";
  const PolygonLayer layer = load_layer(kGeo + GetParam());
  const FlatPolygonIndex index = build_polygon_index(view_of(layer), {});
  const PolygonIndexView view = open_view(layer, index);
  auto points = random_points(layer.bounds, test::kSanitized ? 5000 : 100000, 5);
  const auto boundary = boundary_points(layer, test::kSanitized ? 97 : 7);
  points.insert(points.end(), boundary.begin(), boundary.end());
  expect_agrees(layer, view, points, GetParam());
}

INSTANTIATE_TEST_SUITE_P(PolygonIndex, SharedLayers,
                         ::testing::Values("us-counties-10m.geojson.zst",
                                           "us-states-10m.geojson.zst",
                                           "countries-land-10km.geojson.zst"));

// Every edge two counties share (the same two vertices): its endpoints and midpoint fall in
// one of the two at most, never both, and the midpoint in exactly one when the two lie on opposite
// sides of it. (The 1:10M layer is not a perfect partition: simplification left a few slivers where
// counties overlap, so a few shared edges have both counties on one side; the brute-force
// comparison covers those.)
TEST(PolygonIndex, SharedCountyBordersGoToExactlyOneSide) {
  if (!have_shared()) GTEST_SKIP() << "../shared/data/geo is absent";
  const PolygonLayer layer = load_layer(kGeo + "us-counties-10m.geojson.zst");
  const FlatPolygonIndex index = build_polygon_index(view_of(layer), {});
  const PolygonIndexView view = open_view(layer, index);
  struct Edge {
    Double2 a, b;
    std::uint32_t feature;
    bool interior_left;  // the feature's interior lies left of a -> b
  };
  std::vector<Edge> edges;
  for (std::size_t f = 0; f < layer.feature_count(); ++f)
    for (auto q = layer.feature_polygons[f]; q < layer.feature_polygons[f + 1]; ++q)
      for (auto r = layer.polygon_rings[q]; r < layer.polygon_rings[q + 1]; ++r) {
        const auto lo = layer.ring_vertices[r], hi = layer.ring_vertices[r + 1];
        double area = 0;  // twice the signed area: > 0 counter-clockwise
        for (auto i = lo; i < hi; ++i) {
          const Double2 a = layer.vertices[i], b = layer.vertices[i + 1 == hi ? lo : i + 1];
          area += a.x * b.y - a.y * b.x;
        }
        const bool hole = r != layer.polygon_rings[q];
        for (auto i = lo; i < hi; ++i) {
          Double2 a = layer.vertices[i], b = layer.vertices[i + 1 == hi ? lo : i + 1];
          bool left = (area > 0) != hole;
          if (std::tie(b.x, b.y) < std::tie(a.x, a.y)) std::swap(a, b), left = !left;
          edges.push_back({a, b, std::uint32_t(f), left});
        }
      }
  std::sort(edges.begin(), edges.end(), [](const Edge& l, const Edge& r) {
    return std::tie(l.a.x, l.a.y, l.b.x, l.b.y, l.feature) <
           std::tie(r.a.x, r.a.y, r.b.x, r.b.y, r.feature);
  });
  std::vector<std::uint32_t> all;
  std::size_t shared = 0, overlapping = 0, anomalies = 0;
  for (std::size_t i = 0; i + 1 < edges.size(); ++i) {
    const Edge &e = edges[i], &g = edges[i + 1];
    if (!(e.a == g.a && e.b == g.b) || e.feature == g.feature) continue;
    if (e.interior_left == g.interior_left) {  // both on one side: the layer overlaps itself
      ++overlapping;
      continue;
    }
    if (++shared % (test::kSanitized ? 16 : 1)) continue;
    for (const Double2 p :
         {e.a, e.b, Double2{0.5 * e.a.x + 0.5 * e.b.x, 0.5 * e.a.y + 0.5 * e.b.y}}) {
      view.locate_all(p, all);
      const auto n = std::count(all.begin(), all.end(), e.feature) +
                     std::count(all.begin(), all.end(), g.feature);
      // A vertex may belong to a third county. A point falls in neither or both only where the
      // layer's simplification left a zero-width spike (Stanislaus runs up and back down the
      // edge it shares with Alameda at -121.471, 37.482) or a sliver (Morehouse folds back over
      // Ouachita at -91.908, 32.511); the brute-force test agrees there. Rare: counted.
      if (p == e.a || p == e.b)
        anomalies += n > 1;
      else
        anomalies += n != 1;
    }
  }
  EXPECT_GT(shared, 5000u);
  EXPECT_LT(overlapping, shared / 100);
  EXPECT_LT(anomalies, shared / 1000);
}

// The 42,049 ZIP points of the shared data, (longitude, latitude) in file order.
std::vector<Double2> zip_points() {
  const InputBytes csv = read_input_bytes(kGeo + "zipcodes.csv.zst");
  CsvReader reader("zipcodes.csv", std::string_view(reinterpret_cast<const char*>(csv.bytes.data()),
                                                    csv.bytes.size()));
  std::vector<std::string_view> fields;
  std::vector<Double2> points;
  if (!reader.next(fields)) return points;
  const auto lat = csv_column(fields, "latitude"), lon = csv_column(fields, "longitude");
  if (!lat || !lon) return points;
  while (reader.next(fields))
    points.push_back({std::stod(std::string(fields[*lon])), std::stod(std::string(fields[*lat]))});
  return points;
}

TEST(PolygonIndex, ZipPointsFallInTheCountiesTheManifestSays) {
  if (!have_shared()) GTEST_SKIP() << "../shared/data/geo is absent";
  const PolygonLayer layer = load_layer(kGeo + "us-counties-10m.geojson.zst");
  const FlatPolygonIndex index = build_polygon_index(view_of(layer), {});
  const PolygonIndexView view = open_view(layer, index);
  const std::vector<Double2> points = zip_points();
  ASSERT_EQ(points.size(), 42049u);
  std::size_t one = 0, none = 0, two = 0;
  std::vector<std::uint32_t> all;
  for (const Double2& p : points) {
    view.locate_all(p, all);
    (all.empty() ? none : all.size() == 1 ? one : two)++;
  }
  EXPECT_EQ(one, 41603u);
  EXPECT_EQ(none, 446u);
  EXPECT_EQ(two, 0u);
}

// ---- determinism and forged bytes -----------------------------------------------------------

TEST(PolygonIndex, SameBytesOnAnyThreadCount) {
  const PolygonLayer layer =
      have_shared() ? load_layer(kGeo + "us-states-10m.geojson.zst") : shapes();
  const auto one = build_polygon_index(view_of(layer), {16, 16, 1});
  for (const unsigned threads : {2u, 8u}) {
    const auto other = build_polygon_index(view_of(layer), {16, 16, threads});
    ASSERT_EQ(one.nodes.size(), other.nodes.size());
    ASSERT_EQ(one.entries.size(), other.entries.size());
    ASSERT_EQ(one.edges.size(), other.edges.size());
    EXPECT_EQ(std::memcmp(one.nodes.data(), other.nodes.data(), one.nodes.size() * 8), 0);
    EXPECT_EQ(std::memcmp(one.entries.data(), other.entries.data(), one.entries.size() * 12), 0);
    EXPECT_EQ(std::memcmp(one.edges.data(), other.edges.data(), one.edges.size() * 8), 0);
  }
}

// Flips bytes of every section: the view refuses them (BlobError) or every answer stays a
// feature index or kNone, and the walks end.
TEST(PolygonIndex, ForgedSectionsAreRefusedOrSafe) {
  const PolygonLayer layer = shapes();
  const FlatPolygonIndex good = build_polygon_index(view_of(layer), {2, 8, 1});
  std::mt19937_64 rng(13);
  const auto probes = random_points(layer.bounds, 200, 17);
  int refused = 0, opened = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    FlatPolygonIndex bad = good;
    std::span<std::byte> bytes[] = {std::as_writable_bytes(std::span(bad.nodes)),
                                    std::as_writable_bytes(std::span(bad.entries)),
                                    std::as_writable_bytes(std::span(bad.edges))};
    auto& section = bytes[trial % 3];
    if (section.empty()) continue;
    for (int k = 0; k < 1 + trial % 3; ++k)
      section[rng() % section.size()] ^= std::byte(1u << (rng() % 8));
    try {
      const PolygonIndexView view = open_view(layer, bad);
      ++opened;
      std::vector<std::uint32_t> out;
      std::vector<IndexCell2> cells;
      for (const Double2& p : probes) {
        const auto f = view.locate(p);
        ASSERT_TRUE(f == PolygonQueries::kNone || f < layer.feature_count());
        view.locate_all(p, out);
        for (auto g : out) ASSERT_LT(g, layer.feature_count());
      }
      std::vector<std::uint32_t> many(probes.size());
      view.locate_many(probes, many);
      for (std::size_t i = 0; i < probes.size(); ++i) ASSERT_EQ(many[i], view.locate(probes[i]));
      view.features_in_box(layer.bounds, out);
      for (auto g : out) ASSERT_LT(g, layer.feature_count());
      view.cells(cells);
    } catch (const BlobError&) {
      ++refused;
    }
  }
  EXPECT_GT(refused, 0);
  EXPECT_GT(opened, 0);
}

// A node nothing reaches may hold anything (the validation walks the tree from the root): an
// interior node whose children lie far out of range is never read, and answers stay the tree's.
TEST(PolygonIndex, UnreachedNodesAreNeverRead) {
  const PolygonLayer layer = shapes();
  const FlatPolygonIndex good = build_polygon_index(view_of(layer), {2, 8, 1});
  FlatPolygonIndex bad = good;
  bad.nodes.push_back({0xFFFFFFF0u, format::kPolygonNodeInterior});
  const PolygonIndexView want = open_view(layer, good), got = open_view(layer, bad);
  for (const Double2& p : random_points(layer.bounds, 2000, 23))
    ASSERT_EQ(got.locate(p), want.locate(p));
}

// Forged ranges that overlap (every leaf naming all entries, every entry all edges) would make the
// leaf records derived at open far larger than the sections: the view refuses them.
TEST(PolygonIndex, OverlappingRangesAreRefusedBeforeTheRecordsGrow) {
  const PolygonLayer layer = shapes();
  FlatPolygonIndex bad = build_polygon_index(view_of(layer), {2, 8, 1});
  ASSERT_GT(bad.nodes.size(), 1u);
  for (auto& entry : bad.entries)
    if (!entry.wholly_inside())
      entry = {entry.polygon, 0,
               std::uint32_t(bad.edges.size()) | (entry.edge_count & format::kPolygonCentreInside)};
  EXPECT_THROW(open_view(layer, bad), BlobError);
}

// ---- blobs: round trips, determinism, forged bytes, dump, verify, kiln query ----------------

Scene scene_of(PolygonLayer layer) {
  Scene scene;
  scene.polygons = std::move(layer);
  return scene;
}

// Opens the blob's polygon index through the registry and checks its answers against the
// in-memory view's on `points`.
void expect_blob_answers(std::span<const std::byte> bytes, const PolygonIndexView& want,
                         const std::vector<Double2>& points) {
  const AlignedBuffer copy = test::aligned_copy(bytes);
  const Blob blob = Blob::open_memory(copy.bytes());
  blob.verify();
  const auto view = open_structure(blob, "polygon-index");
  const PolygonQueries* q = view->polygons();
  ASSERT_NE(q, nullptr);
  std::vector<std::uint32_t> got, expected;
  for (const Double2& p : points) {
    ASSERT_EQ(q->locate(p), want.locate(p));
    q->locate_all(p, got);
    want.locate_all(p, expected);
    ASSERT_EQ(got, expected);
  }
  std::vector<IndexCell2> cells;
  q->cells(cells);
  EXPECT_FALSE(cells.empty());
}

TEST(PolygonIndexBlob, RoundTripsThroughMemoryFileAndZstd) {
  const PolygonLayer layer = shapes();
  const FlatPolygonIndex index = build_polygon_index(view_of(layer), {});
  const PolygonIndexView want = open_view(layer, index);
  auto points = boundary_points(layer, 1);
  const auto more = random_points(layer.bounds, 500, 21);
  points.insert(points.end(), more.begin(), more.end());
  for (const bool compress : {false, true})
    expect_blob_answers(test::blob_with(scene_of(layer), "polygon-index", 2, compress), want,
                        points);
  test::TempDir dir;
  test::write_file(dir.file("shapes.kiln"), test::blob_with(scene_of(layer), "polygon-index", 2));
  const Blob blob = Blob::open_file(dir.file("shapes.kiln"));
  EXPECT_EQ(open_structure(blob, "polygon-index")->polygons()->locate({1, 1}), 0u);
}

TEST(PolygonIndexBlob, ByteIdenticalOnOneTwoAndEightThreads) {
  const Scene scene =
      scene_of(have_shared() ? load_layer(kGeo + "us-counties-10m.geojson.zst") : shapes());
  const auto one = test::blob_with(scene, "polygon-index:max-edges=8", 1);
  EXPECT_EQ(test::blob_with(scene, "polygon-index:max-edges=8", 2), one);
  EXPECT_EQ(test::blob_with(scene, "polygon-index:max-edges=8", 8), one);
}

// Flips bytes in each of the structure's sections (checksums recomputed, so only the view's
// walk can catch them): open and verify throw BlobError, or every answer stays in range.
TEST(PolygonIndexBlob, ForgedSectionsAreRefusedOrAnswerInRange) {
  const PolygonLayer layer = shapes();
  const auto bytes = test::blob_with(scene_of(layer), "polygon-index:max-edges=2", 1);
  const AlignedBuffer copy = test::aligned_copy(bytes);
  const Blob blob = Blob::open_memory(copy.bytes());
  const auto sections = blob.structure("polygon-index")->sections;
  ASSERT_EQ(sections.size(), 3u);
  const auto probes = random_points(layer.bounds, 100, 23);
  std::mt19937_64 rng(29);
  for (const std::uint32_t section : sections) {
    const std::size_t size = blob.section_bytes(section).size();
    int refused = 0;
    for (int trial = 0; trial < 150; ++trial) {
      std::byte flip[1] = {std::byte(1u << (rng() % 8))};
      const std::size_t at = rng() % size;
      flip[0] ^= blob.section_bytes(section)[at];
      const AlignedBuffer forged =
          test::aligned_copy(test::with_patched_section(bytes, section, at, flip));
      try {
        const Blob bad = Blob::open_memory(forged.bytes());
        const auto view = open_structure(bad, "polygon-index");
        std::vector<std::uint32_t> out;
        for (const Double2& p : probes) {
          const auto f = view->polygons()->locate(p);
          ASSERT_TRUE(f == PolygonQueries::kNone || f < layer.feature_count());
          view->polygons()->locate_all(p, out);
          for (const auto g : out) ASSERT_LT(g, layer.feature_count());
        }
        view->polygons()->features_in_box(layer.bounds, out);
        for (const auto g : out) ASSERT_LT(g, layer.feature_count());
        bad.verify();  // may throw: a wrong edge is caught here
      } catch (const BlobError&) {
        ++refused;
      }
    }
    EXPECT_GT(refused, 0) << "section " << section;
  }
}

// The capability's batch call (what `kiln query` and the Python module run) answers as locate
// per point, on one, two and every thread, in runs that cross its 4,096-point runs unevenly.
TEST(PolygonIndexBlob, BatchCallAnswersAsLocateOnAnyThreadCount) {
  const PolygonLayer layer =
      have_shared() ? load_layer(kGeo + "us-counties-10m.geojson.zst") : shapes();
  const AlignedBuffer copy =
      test::aligned_copy(test::blob_with(scene_of(layer), "polygon-index", 2));
  const Blob blob = Blob::open_memory(copy.bytes());
  const auto view = open_structure(blob, "polygon-index");
  const PolygonQueries& q = *view->polygons();
  auto points = random_points(layer.bounds, 9001, 31);
  const auto boundary = boundary_points(layer, test::kSanitized ? 101 : 11);
  points.insert(points.end(), boundary.begin(), boundary.end());
  points.push_back({std::nan(""), 1});
  points.push_back({layer.bounds.min.x, INFINITY});
  std::vector<std::uint32_t> want(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) want[i] = q.locate(points[i]);
  for (const unsigned threads : {1u, 2u, 0u}) {
    std::vector<std::uint32_t> got(points.size(), 12345);
    q.locate_many(points, got, threads);
    ASSERT_EQ(got, want) << threads << " threads";
  }
  std::vector<std::uint32_t> short_out(points.size() - 1);
  EXPECT_THROW(q.locate_many(points, short_out, 1), std::invalid_argument);
}

// The ZIP points through `kiln query --op polygon` (CSV in and binary in, the batch call) on one
// and two threads: the same bytes, and per point the lowest county containing it (the
// descent's locate_all, itself checked against brute force above): 446 in none.
TEST(PolygonIndexBlob, ZipPointsFromTheCommandLineOnOneAndTwoThreads) {
  if (!have_shared()) GTEST_SKIP() << "../shared/data/geo is absent";
  test::TempDir dir;
  const std::string blob = dir.file("counties.kiln");
  test::write_file(blob, test::blob_with(scene_of(load_layer(kGeo + "us-counties-10m.geojson.zst")),
                                         "polygon-index", 2));
  const Blob opened = Blob::open_file(blob);
  const auto structure = open_structure(opened, "polygon-index");
  const PolygonQueries& view = *structure->polygons();
  std::vector<double> xy;
  std::vector<std::uint32_t> want, all;
  for (const Double2& p : zip_points()) {
    xy.push_back(p.x);
    xy.push_back(p.y);
    view.locate_all(p, all);
    want.push_back(all.empty() ? PolygonQueries::kNone : all[0]);
  }
  ASSERT_EQ(std::count(want.begin(), want.end(), PolygonQueries::kNone), 446);
  test::write_file(dir.file("zip.bin"), std::as_bytes(std::span(xy)));
  const std::string query = "query " + test::quoted(blob) + " --op polygon --in ";
  std::string text[2];
  for (const unsigned threads : {1u, 2u}) {
    const std::string t = " --threads " + std::to_string(threads) + " --out ";
    const std::string bin = dir.file("zip" + std::to_string(threads) + ".out");
    auto r = test::run_kiln(query + test::quoted(dir.file("zip.bin")) + t + test::quoted(bin));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto out = test::read_file(bin);
    ASSERT_EQ(out.size(), want.size() * 4);
    std::vector<std::uint32_t> got(want.size());
    std::memcpy(got.data(), out.data(), out.size());
    EXPECT_EQ(got, want) << threads << " threads";
    const std::string csv_out = dir.file("zip" + std::to_string(threads) + ".csv");
    r = test::run_kiln(query + test::quoted(kGeo + "zipcodes.csv.zst") +
                       " --lon-column longitude --lat-column latitude" + t + test::quoted(csv_out));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    text[threads - 1] = test::read_text(csv_out);
  }
  EXPECT_EQ(text[0], text[1]);
  CsvReader rows("zip1.csv", text[0]);
  std::vector<std::string_view> fields;
  ASSERT_TRUE(rows.next(fields));
  const auto column = csv_column(fields, "polygon_index");
  ASSERT_TRUE(column);
  for (std::size_t i = 0; rows.next(fields); ++i) {
    ASSERT_LT(i, want.size());
    const long f = std::stol(std::string(fields[*column]));
    ASSERT_EQ(f, want[i] == PolygonQueries::kNone ? -1L : long(want[i])) << "row " << i;
  }
}

TEST(PolygonIndexBlob, DumpVerifyAndQueryFromTheCommandLine) {
  PolygonLayer layer = shapes();
  layer.names = {};
  for (const char* name : {"Square, with a \"hole\"", "Left", "Right", "Twins", "Over"})
    layer.names.push(name);
  test::TempDir dir;
  const std::string blob = dir.file("shapes.kiln");
  test::write_file(blob, test::blob_with(scene_of(layer), "polygon-index", 2));
  const auto dump = test::run_kiln("dump " + test::quoted(blob));
  ASSERT_EQ(dump.exit_code, 0) << dump.err;
  EXPECT_NE(dump.out.find("max 8 edges per cell"), std::string::npos) << dump.out;
  EXPECT_NE(dump.out.find("level 1:"), std::string::npos) << dump.out;
  const auto json = test::run_kiln("dump --json " + test::quoted(blob));
  ASSERT_EQ(json.exit_code, 0) << json.err;
  EXPECT_NE(json.out.find("\"bytes_per_vertex\""), std::string::npos) << json.out;
  EXPECT_NE(json.out.find("\"edges_per_boundary_leaf\""), std::string::npos);
  EXPECT_EQ(test::run_kiln("verify " + test::quoted(blob)).exit_code, 0);

  test::write_text(dir.file("in.csv"), "name,lon,lat\n\"a, b\",1,1\nhole,5,5\nover,9,9\n");
  const std::string csv = "query " + test::quoted(blob) + " --op polygon --in " +
                          test::quoted(dir.file("in.csv")) + " --lon-column lon --lat-column lat";
  auto r = test::run_kiln(csv + " --out " + test::quoted(dir.file("out.csv")));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(test::read_text(dir.file("out.csv")),
            "name,lon,lat,polygon_index,polygon_id,polygon_name\n"
            "\"a, b\",1,1,0,0,\"Square, with a \"\"hole\"\"\"\n"
            "hole,5,5,-1,,\n"
            "over,9,9,0,0,\"Square, with a \"\"hole\"\"\"\n");
  r = test::run_kiln(csv + " --all --out " + test::quoted(dir.file("all.csv")));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(test::read_text(dir.file("all.csv")).find("over,9,9,4,4,Over\n"), std::string::npos);

  const double xy[] = {1, 1, 5, 5, 15, 5};
  test::write_file(dir.file("in.bin"), std::as_bytes(std::span(xy)));
  r = test::run_kiln("query " + test::quoted(blob) + " --op polygon --in " +
                     test::quoted(dir.file("in.bin")) + " --out " +
                     test::quoted(dir.file("out.bin")));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto out = test::read_file(dir.file("out.bin"));
  ASSERT_EQ(out.size(), 12u);
  std::uint32_t got[3];
  std::memcpy(got, out.data(), 12);
  EXPECT_EQ(got[0], 0u);
  EXPECT_EQ(got[1], PolygonQueries::kNone);
  EXPECT_EQ(got[2], 1u);

  test::write_text(dir.file("boxes.csv"), "min_x,min_y,max_x,max_y\n4,4,6,6\n9,9,11,11\n");
  r = test::run_kiln("query " + test::quoted(blob) + " --op polygons-in-box --in " +
                     test::quoted(dir.file("boxes.csv")) + " --out " +
                     test::quoted(dir.file("b.csv")));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(test::read_text(dir.file("b.csv")), "box_index,feature_index\n1,0\n1,1\n1,4\n");

  test::write_text(dir.file("bad.csv"), "lon,lat\n1,x\n");
  r = test::run_kiln("query " + test::quoted(blob) + " --op polygon --in " +
                     test::quoted(dir.file("bad.csv")) +
                     " --lon-column lon --lat-column lat --out " + test::quoted(dir.file("o.csv")));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("bad.csv:2"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace kiln
