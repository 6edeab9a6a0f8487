// Maps of 2D blobs: polygons filled by scanlines (even-odd over every ring of a feature),
// outlines, points as dots, the index's cells, or a heatmap of per-query cost, in an
// equirectangular projection fitted to the layer's bounds (across the antimeridian when that
// frames it tighter).
#include "kiln/tools/render_map.hpp"

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "kiln/runtime/parallel.hpp"

namespace kiln::render {

namespace {

// ColorBrewer's Set3: twelve light colours that keep dark outlines and dots readable.
constexpr Rgb kPalette[12] = {{141, 211, 199}, {255, 255, 179}, {190, 186, 218}, {251, 128, 114},
                              {128, 177, 211}, {253, 180, 98},  {179, 222, 105}, {252, 205, 229},
                              {217, 217, 217}, {188, 128, 189}, {204, 235, 197}, {255, 237, 111}};
constexpr Rgb kSea{236, 240, 245};
constexpr Rgb kOutline{70, 70, 80};
constexpr Rgb kHeatOutline{235, 235, 235};
constexpr Rgb kPoint{180, 20, 40};
constexpr Rgb kCell{20, 70, 200};
constexpr double kMargin = 0.02;  // of the image, on every side
// Pixel coordinates are clamped to this before rounding: far outside any image, never UB.
constexpr double kFar = 1e7;

long to_index(double v) {
  return std::lround(std::clamp(v, -kFar, kFar));
}

void plot(Image& image, long x, long y, Rgb c) {
  if (x >= 0 && y >= 0 && x < long(image.width) && y < long(image.height))
    image.at(std::uint32_t(x), std::uint32_t(y)) = c;
}

// A line between pixel positions (Bresenham), clipped pixel by pixel; endpoints outside the
// image are first pulled to its box grown by a pixel, so off-image runs cost nothing.
void draw_line(Image& image, format::Double2 a, format::Double2 b, Rgb c) {
  if (!std::isfinite(a.x + a.y + b.x + b.y)) return;
  const double w = image.width, h = image.height;
  if ((a.x < -1 && b.x < -1) || (a.y < -1 && b.y < -1) || (a.x > w + 1 && b.x > w + 1) ||
      (a.y > h + 1 && b.y > h + 1))
    return;
  long x0 = to_index(a.x - 0.5), y0 = to_index(a.y - 0.5);
  const long x1 = to_index(b.x - 0.5), y1 = to_index(b.y - 0.5);
  const long dx = std::labs(x1 - x0), dy = -std::labs(y1 - y0);
  const long sx = x0 < x1 ? 1 : -1, sy = y0 < y1 ? 1 : -1;
  for (long err = dx + dy;;) {
    plot(image, x0, y0, c);
    if (x0 == x1 && y0 == y1) return;
    const long e2 = 2 * err;
    if (e2 >= dy) err += dy, x0 += sx;
    if (e2 <= dx) err += dx, y0 += sy;
  }
}

// A feature's rings in pixel coordinates.
std::vector<std::vector<format::Double2>> feature_rings(const PolygonLayerView& layer,
                                                        const MapFrame& frame, std::size_t f) {
  std::vector<std::vector<format::Double2>> rings;
  for (auto p = layer.feature_polygons[f]; p < layer.feature_polygons[f + 1]; ++p)
    for (auto r = layer.polygon_rings[p]; r < layer.polygon_rings[p + 1]; ++r) {
      rings.emplace_back();
      for (const auto& v : layer.ring(r)) rings.back().push_back(frame.to_pixel(v));
    }
  return rings;
}

// Even-odd scanline fill at pixel centres: a row's crossings with every edge of every ring
// (half-open in y, so a vertex on the row counts once), sorted, filled pairwise.
void fill_feature(Image& image, const std::vector<std::vector<format::Double2>>& rings, Rgb c) {
  std::vector<std::pair<long, double>> crossings;  // (row, x)
  for (const auto& ring : rings)
    for (std::size_t i = 0; i < ring.size(); ++i) {
      const format::Double2 a = ring[i], b = ring[(i + 1) % ring.size()];
      if (!std::isfinite(a.x + a.y + b.x + b.y) || a.y == b.y) continue;
      const long lo =
          std::max(0L, long(std::ceil(std::clamp(std::min(a.y, b.y), -kFar, kFar) - 0.5)));
      const long hi = std::min(long(image.height) - 1,
                               long(std::ceil(std::clamp(std::max(a.y, b.y), -kFar, kFar) - 0.5)));
      for (long row = lo; row <= hi; ++row) {
        const double yc = double(row) + 0.5;
        if ((a.y <= yc) == (b.y <= yc)) continue;
        crossings.emplace_back(row, a.x + (yc - a.y) * (b.x - a.x) / (b.y - a.y));
      }
    }
  std::sort(crossings.begin(), crossings.end());
  for (std::size_t i = 0; i + 1 < crossings.size(); i += 2) {
    if (crossings[i].first != crossings[i + 1].first) {  // an odd row: cannot happen exactly
      i -= 1;
      continue;
    }
    const long row = crossings[i].first;
    const long from = std::max(0L, to_index(std::ceil(crossings[i].second - 0.5)));
    const long to = std::min(long(image.width), to_index(std::ceil(crossings[i + 1].second - 0.5)));
    for (long x = from; x < to; ++x) image.at(std::uint32_t(x), std::uint32_t(row)) = c;
  }
}

void draw_outlines(Image& image, const std::vector<std::vector<format::Double2>>& rings, Rgb c) {
  for (const auto& ring : rings)
    for (std::size_t i = 0; i < ring.size(); ++i)
      draw_line(image, ring[i], ring[(i + 1) % ring.size()], c);
}

void draw_polygons(Image& image, const PolygonLayerView& layer, const MapFrame& frame, bool fill,
                   Rgb outline) {
  for (std::size_t f = 0; f < layer.feature_count(); ++f) {
    const auto rings = feature_rings(layer, frame, f);
    if (fill) fill_feature(image, rings, feature_colour(f));
  }
  for (std::size_t f = 0; f < layer.feature_count(); ++f)
    draw_outlines(image, feature_rings(layer, frame, f), outline);
}

// Each point as a plus of five pixels.
void draw_points(Image& image, const PointTableView& table, const MapFrame& frame) {
  for (const auto& p : table.points) {
    const format::Double2 q = frame.to_pixel(p);
    if (!std::isfinite(q.x + q.y)) continue;
    const long x = to_index(q.x - 0.5), y = to_index(q.y - 0.5);
    for (const auto& [ox, oy] : {std::pair{0L, 0L}, {1L, 0L}, {-1L, 0L}, {0L, 1L}, {0L, -1L}})
      plot(image, x + ox, y + oy, kPoint);
  }
}

std::uint64_t draw_cells(Image& image, const MapContent& content, const MapFrame& frame) {
  std::vector<IndexCell2> cells;
  if (content.polygon_index)
    content.polygon_index->cells(cells);
  else
    content.point_index->cells(cells);
  for (const IndexCell2& c : cells) {
    if (frame.wrap() && c.box.min.x < 0 && c.box.max.x >= 0) continue;  // would span the map
    const format::Double2 a = frame.to_pixel(c.box.min), b = frame.to_pixel(c.box.max);
    draw_line(image, a, {b.x, a.y}, kCell);
    draw_line(image, {b.x, a.y}, b, kCell);
    draw_line(image, b, {a.x, b.y}, kCell);
    draw_line(image, {a.x, b.y}, a, kCell);
  }
  return cells.size();
}

// One query per pixel centre, counted: locate for a polygon layer, else a one-pixel box range.
Samples heat_samples(const MapContent& content, const MapFrame& frame, unsigned threads) {
  const Size size = frame.size();
  Samples samples{size, std::vector<Sample>(std::size_t(size.width) * size.height)};
  const double half = 0.5 * frame.pixel_size();
  parallel_for(size.height, threads, [&](std::size_t row) {
    std::vector<std::uint32_t> found;
    for (std::uint32_t x = 0; x < size.width; ++x) {
      const format::Double2 p = frame.pixel_centre(x, std::uint32_t(row));
      Cost cost;
      if (content.polygon_index)
        content.polygon_index->locate_counting(p, cost);
      else
        content.point_index->range_counting({{p.x - half, p.y - half}, {p.x + half, p.y + half}},
                                            found, cost);
      Sample& s = samples.pixels[row * size.width + x];
      s.nodes = cost.nodes, s.tests = cost.tests;
    }
  });
  return samples;
}

Image draw_heatmap(const MapContent& content, const MapFrame& frame, unsigned threads,
                   MapStats& stats) {
  const Samples samples = heat_samples(content, frame, threads);
  const Samples* all[] = {&samples};
  stats.heat_scale = heatmap_scale(all);
  const CostSummary summary = summarize(samples);
  stats.mean_cost = summary.mean_cost, stats.max_cost = summary.max_cost;
  Image image(frame.size().width, frame.size().height);
  for (std::size_t i = 0; i < image.pixels.size(); ++i)
    image.pixels[i] = heat_colour(samples.pixels[i].cost(), stats.heat_scale);
  // Outlines keep the map readable; dots would hide the dense areas the heatmap is about.
  if (content.polygons) draw_polygons(image, *content.polygons, frame, false, kHeatOutline);
  draw_legend(image, stats.heat_scale, stats.max_cost > stats.heat_scale,
              content.polygon_index ? "cost per point query: cells visited + edges tested"
                                    : "cost per pixel box query: nodes visited + points tested");
  return image;
}

// The layer's bounds, or, for longitudes and latitudes whose span shrinks by a quarter or more
// when the western ones move 360 degrees east, those wrapped bounds (a gap around 0 degrees:
// no ring crosses it).
MapFrame fit_frame(const MapContent& content, Size size) {
  format::Box2d bounds, wrapped;
  auto grow = [&](const format::Double2& p) {
    bounds.grow(p);
    wrapped.grow(format::Double2{p.x < 0 ? p.x + 360 : p.x, p.y});
  };
  if (content.polygons)
    for (const auto& v : content.polygons->vertices) grow(v);
  if (content.points)
    for (const auto& p : content.points->points) grow(p);
  const bool geographic =
      bounds.min.x >= -180 && bounds.max.x <= 180 && bounds.min.y >= -90 && bounds.max.y <= 90;
  const bool wrap =
      geographic && wrapped.max.x - wrapped.min.x < 0.75 * (bounds.max.x - bounds.min.x);
  return MapFrame(wrap ? wrapped : bounds, size, wrap);
}

}  // namespace

std::optional<MapMode> parse_map_mode(std::string_view name) {
  if (name == "map") return MapMode::kPlain;
  if (name == "cells") return MapMode::kCells;
  if (name == "heatmap") return MapMode::kHeatmap;
  return std::nullopt;
}

MapFrame::MapFrame(const format::Box2d& bounds, Size size, bool wrap) : size_(size), wrap_(wrap) {
  const double w = bounds.max.x - bounds.min.x, h = bounds.max.y - bounds.min.y;
  const double usable_w = size.width * (1 - 2 * kMargin),
               usable_h = size.height * (1 - 2 * kMargin);
  scale_ = std::min(w > 0 ? usable_w / w : INFINITY, h > 0 ? usable_h / h : INFINITY);
  if (!std::isfinite(scale_) || !(scale_ > 0)) scale_ = 1;  // one point, or an empty layer
  const double cx = 0.5 * bounds.min.x + 0.5 * bounds.max.x;
  const double cy = 0.5 * bounds.min.y + 0.5 * bounds.max.y;
  left_ = std::isfinite(cx) ? cx - 0.5 * size.width / scale_ : 0;
  top_ = std::isfinite(cy) ? cy + 0.5 * size.height / scale_ : 0;
}

format::Double2 MapFrame::to_pixel(const format::Double2& p) const {
  const double x = wrap_ && p.x < 0 ? p.x + 360 : p.x;
  return {(x - left_) * scale_, (top_ - p.y) * scale_};
}

format::Double2 MapFrame::pixel_centre(std::uint32_t i, std::uint32_t j) const {
  const double x = left_ + (i + 0.5) / scale_;
  return {wrap_ && x >= 180 ? x - 360 : x, top_ - (j + 0.5) / scale_};
}

Rgb feature_colour(std::uint64_t feature) {
  // SplitMix64's finaliser: neighbouring indices land on unrelated colours.
  std::uint64_t z = feature + 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return kPalette[(z ^ (z >> 31)) % 12];
}

Image draw_map(const MapContent& content, MapMode mode, Size size, unsigned threads,
               MapStats* stats) {
  if (!content.polygons && !content.points) throw std::invalid_argument("nothing to draw");
  const bool indexed = content.polygon_index || content.point_index;
  if (mode != MapMode::kPlain && !indexed)
    throw std::invalid_argument("--mode cells and heatmap need a 2D index (build one: --accel)");
  const MapFrame frame = fit_frame(content, size);
  MapStats local;
  MapStats& s = stats ? *stats : local;
  s = {};
  if (mode == MapMode::kHeatmap) return draw_heatmap(content, frame, threads, s);
  Image image(size.width, size.height, kSea);
  if (content.polygons) draw_polygons(image, *content.polygons, frame, true, kOutline);
  if (content.points) draw_points(image, *content.points, frame);
  if (mode == MapMode::kCells) s.cells = draw_cells(image, content, frame);
  return image;
}

namespace {

// Web-Mercator pixels of tile `t`: x east, y south, kTileSize per tile side.
format::Double2 tile_pixel(const format::Double2& p, TileAddress t) {
  constexpr double kPi = 3.14159265358979323846, kMaxLat = 85.0511287798066;
  const double world = std::ldexp(double(kTileSize), int(t.z));
  const double lat = std::clamp(p.y, -kMaxLat, kMaxLat) * kPi / 180.0;
  return {(p.x + 180.0) / 360.0 * world - double(t.x) * kTileSize,
          (1.0 - std::asinh(std::tan(lat)) / kPi) / 2.0 * world - double(t.y) * kTileSize};
}

// A feature's rings in the tile's pixels, or none when its box misses the tile (most features
// of a zoomed-in tile: skipped after one pass over their vertices).
std::vector<std::vector<format::Double2>> tile_rings(const PolygonLayerView& layer, TileAddress t,
                                                     std::size_t f) {
  std::vector<std::vector<format::Double2>> rings;
  format::Box2d box;
  for (auto p = layer.feature_polygons[f]; p < layer.feature_polygons[f + 1]; ++p)
    for (auto r = layer.polygon_rings[p]; r < layer.polygon_rings[p + 1]; ++r) {
      rings.emplace_back();
      for (const auto& v : layer.ring(r)) box.grow(rings.back().emplace_back(tile_pixel(v, t)));
    }
  const double side = kTileSize;
  if (box.max.x < -1 || box.max.y < -1 || box.min.x > side + 1 || box.min.y > side + 1) return {};
  return rings;
}

}  // namespace

Image draw_polygon_tile(const PolygonLayerView& layer, TileAddress tile) {
  if (!tile.valid()) throw std::invalid_argument("no such tile");
  Image image(kTileSize, kTileSize, kSea);
  std::vector<std::vector<std::vector<format::Double2>>> rings(layer.feature_count());
  for (std::size_t f = 0; f < layer.feature_count(); ++f) {
    rings[f] = tile_rings(layer, tile, f);
    fill_feature(image, rings[f], feature_colour(f));
  }
  for (const auto& feature : rings) draw_outlines(image, feature, kOutline);
  return image;
}

}  // namespace kiln::render
