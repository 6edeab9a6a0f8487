// Maps of 2D layers (`kiln render` on a 2D blob): a hand-made layer's fill, hole and background
// at known pixels; the cells and heatmap modes differ from the plain map where they should;
// the same bytes for any thread count.
#include <gtest/gtest.h>

#include <cmath>
#include <span>
#include <vector>

#include "kiln/compiler/quadtree_builder.hpp"
#include "kiln/runtime/quadtree.hpp"
#include "kiln/tools/render_map.hpp"

namespace kiln {
namespace {

using format::Box2d;
using format::Double2;

constexpr render::Rgb kSea{236, 240, 245};

bool same(const render::Rgb& a, const render::Rgb& b) {
  return a.r == b.r && a.g == b.g && a.b == b.b;
}

// Feature 0: the square [0, 10]^2 with the hole [4, 6]^2. Feature 1: two squares, [12, 16] x
// [0, 4] and [12, 16] x [6, 10] (a multipolygon).
struct Layer {
  std::vector<Double2> vertices{{0, 0},  {10, 0}, {10, 10}, {0, 10}, {4, 4},  {6, 4},
                                {6, 6},  {4, 6},  {12, 0},  {16, 0}, {16, 4}, {12, 4},
                                {12, 6}, {16, 6}, {16, 10}, {12, 10}};
  std::vector<std::uint64_t> rings{0, 4, 8, 12, 16};
  std::vector<std::uint64_t> polygons{0, 2, 3, 4};
  std::vector<std::uint64_t> features{0, 1, 3};
  PolygonLayerView view() const {
    PolygonLayerView v;
    v.vertices = vertices, v.ring_vertices = rings, v.polygon_rings = polygons;
    v.feature_polygons = features;
    v.bounds = {{0, 0}, {16, 10}};
    return v;
  }
};

// Point in polygon by crossing number over every edge of every feature (the reference a polygon
// index must agree with), counting every edge as a test: enough to draw a heatmap.
class BruteLocate final : public PolygonQueries {
 public:
  explicit BruteLocate(PolygonLayerView layer) : layer_(layer) {}
  std::uint32_t locate(const Double2& p) const override {
    Cost cost;
    return locate_counting(p, cost);
  }
  void locate_many(std::span<const Double2> points, std::span<std::uint32_t> out,
                   unsigned) const override {
    for (std::size_t i = 0; i < points.size(); ++i) out[i] = locate(points[i]);
  }
  std::uint32_t locate_counting(const Double2& p, Cost& cost) const override {
    cost.nodes += 1;
    for (std::size_t f = 0; f < layer_.feature_count(); ++f) {
      bool in = false;
      for (auto r = layer_.polygon_rings[layer_.feature_polygons[f]];
           r < layer_.polygon_rings[layer_.feature_polygons[f + 1]]; ++r) {
        const auto ring = layer_.ring(r);
        for (std::size_t i = 0; i < ring.size(); ++i) {
          const Double2 a = ring[i], b = ring[(i + 1) % ring.size()];
          cost.tests += 1;
          if ((a.y <= p.y) != (b.y <= p.y) && p.x < a.x + (p.y - a.y) * (b.x - a.x) / (b.y - a.y))
            in = !in;
        }
      }
      if (in) return std::uint32_t(f);
    }
    return kNone;
  }
  void locate_all(const Double2&, std::vector<std::uint32_t>& out) const override { out.clear(); }
  void features_in_box(const Box2d&, std::vector<std::uint32_t>& out) const override {
    out.clear();
  }
  void cells(std::vector<IndexCell2>& out) const override {
    out = {{{{0, 0}, {8, 10}}, 1, 3}, {{{8, 0}, {16, 10}}, 1, 5}};
  }

 private:
  PolygonLayerView layer_;
};

class QuadtreeIndex final : public Point2Queries {
 public:
  explicit QuadtreeIndex(const QuadtreeView& v) : v_(v) {}
  void range(const Box2d& b, std::vector<std::uint32_t>& out) const override { v_.range(b, out); }
  void range_counting(const Box2d& b, std::vector<std::uint32_t>& out, Cost& c) const override {
    v_.range_counting(b, out, c);
  }
  std::size_t nearest(const Double2& q, std::span<Neighbor2> out) const override {
    return v_.nearest(q, out);
  }
  void within_radius(const Double2& q, double r, std::vector<Neighbor2>& out) const override {
    v_.within_radius(q, r, out);
  }
  void cells(std::vector<IndexCell2>& out) const override { v_.cells(out); }

 private:
  const QuadtreeView& v_;
};

render::Rgb pixel_at(const render::Image& image, const render::MapFrame& frame, Double2 p) {
  const Double2 q = frame.to_pixel(p);
  return image.at(std::uint32_t(q.x), std::uint32_t(q.y));
}

TEST(RenderMap, FillsFeaturesLeavesHolesAndSeaOpen) {
  const Layer layer;
  const PolygonLayerView view = layer.view();
  render::MapContent content;
  content.polygons = &view;
  const render::Size size{320, 200};
  const render::Image image = render::draw_map(content, render::MapMode::kPlain, size, 1);
  const render::MapFrame frame(view.bounds, size);
  EXPECT_TRUE(same(pixel_at(image, frame, {2, 2}), render::feature_colour(0)));
  EXPECT_TRUE(same(pixel_at(image, frame, {8, 7}), render::feature_colour(0)));
  EXPECT_TRUE(same(pixel_at(image, frame, {5, 5}), kSea)) << "the hole";
  EXPECT_TRUE(same(pixel_at(image, frame, {11, 5}), kSea)) << "between the features";
  EXPECT_TRUE(same(pixel_at(image, frame, {14, 2}), render::feature_colour(1)));
  EXPECT_TRUE(same(pixel_at(image, frame, {14, 8}), render::feature_colour(1)));
  EXPECT_TRUE(same(pixel_at(image, frame, {14, 5}), kSea)) << "between the two polygons";
  EXPECT_FALSE(same(pixel_at(image, frame, {10, 2}), render::feature_colour(0))) << "an outline";
}

TEST(RenderMap, CellsAndHeatmapDifferWhereExpected) {
  const Layer layer;
  const PolygonLayerView view = layer.view();
  const BruteLocate index(view);
  render::MapContent content;
  content.polygons = &view;
  content.polygon_index = &index;
  const render::Size size{320, 200};
  const render::MapFrame frame(view.bounds, size);
  const auto plain = render::draw_map(content, render::MapMode::kPlain, size, 1);
  render::MapStats stats;
  const auto cells = render::draw_map(content, render::MapMode::kCells, size, 1, &stats);
  EXPECT_EQ(stats.cells, 2u);
  // The line between the two cells at x = 8 crosses feature 0; elsewhere the maps agree.
  EXPECT_FALSE(same(pixel_at(cells, frame, {8, 2}), pixel_at(plain, frame, {8, 2})));
  EXPECT_TRUE(same(pixel_at(cells, frame, {2, 2}), pixel_at(plain, frame, {2, 2})));
  const auto heat = render::draw_map(content, render::MapMode::kHeatmap, size, 1, &stats);
  EXPECT_GT(stats.mean_cost, 0);
  // Inside feature 0 a query stops there; outside it tests every edge: a different colour.
  EXPECT_FALSE(same(pixel_at(heat, frame, {2, 2}), pixel_at(heat, frame, {11, 5})));
  EXPECT_FALSE(same(pixel_at(heat, frame, {2, 2}), pixel_at(plain, frame, {2, 2})));
}

TEST(RenderMap, PointTableCellsHeatmapAndDeterminism) {
  std::vector<Double2> points;
  for (int i = 0; i < 2000; ++i)
    points.push_back({std::fmod(i * 0.618034, 1.0) * 40 - 20, std::fmod(i * 0.414214, 1.0) * 20});
  const FlatQuadtree flat = build_quadtree(points, {});
  const QuadtreeView tree(flat.nodes, flat.points, flat.ids, flat.root, points.size());
  const QuadtreeIndex index(tree);
  PointTableView table;
  table.points = points;
  table.bounds = flat.bounds;
  render::MapContent content;
  content.points = &table;
  content.point_index = &index;
  const render::Size size{256, 160};
  const auto plain = render::draw_map(content, render::MapMode::kPlain, size, 1);
  render::MapStats stats;
  const auto cells = render::draw_map(content, render::MapMode::kCells, size, 1, &stats);
  EXPECT_EQ(stats.cells, flat.stats.leaf_count);
  EXPECT_NE(render::encode_png(plain), render::encode_png(cells));
  const auto heat1 = render::draw_map(content, render::MapMode::kHeatmap, size, 1, &stats);
  EXPECT_GT(stats.max_cost, 0u);
  const auto heat4 = render::draw_map(content, render::MapMode::kHeatmap, size, 4);
  EXPECT_EQ(render::encode_png(heat1), render::encode_png(heat4));
  EXPECT_NE(render::encode_png(heat1), render::encode_png(plain));
  render::MapContent bare;
  bare.points = &table;
  EXPECT_THROW(render::draw_map(bare, render::MapMode::kHeatmap, size, 1), std::invalid_argument);
}

}  // namespace
}  // namespace kiln
