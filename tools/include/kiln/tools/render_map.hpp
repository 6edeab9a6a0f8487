// `kiln render` on a 2D blob: a map of its polygon layer or point table (render_map.cpp).
// Projection: equirectangular (plate carrée): x = longitude (or x), y = latitude (or y), one
// scale for both axes, fitted to the layer's bounds with a small margin (across the antimeridian
// when that is tighter); index cells, which are boxes in those coordinates, stay rectangles on the
// map.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "kiln/runtime/capabilities.hpp"
#include "kiln/runtime/geo_layer.hpp"
#include "kiln/tools/render.hpp"

namespace kiln {
class Blob;
}

namespace kiln::render {

enum class MapMode {
  kPlain,    // polygons filled one colour per feature, outlined; points as dots
  kCells,    // the plain map with the index's leaf cells drawn over it
  kHeatmap,  // each pixel coloured by the cost of a point query at its centre, outlines over it
             // (points are left out: they would hide the dense areas)
};
/// "map", "cells", "heatmap".
std::optional<MapMode> parse_map_mode(std::string_view name);

/// Where the map's pixels lie in layer coordinates: `bounds` fitted into `size`, centred. With
/// `wrap`, longitudes below 0 are drawn 360 degrees east (and `bounds` are in those terms), so
/// a layer across the antimeridian (the Aleutians, Pacific islands) stays in one piece.
class MapFrame {
 public:
  MapFrame(const format::Box2d& bounds, Size size, bool wrap = false);
  /// Pixel coordinates (x right, y down; pixel (i, j) covers [i, i+1) x [j, j+1)).
  format::Double2 to_pixel(const format::Double2& p) const;
  /// The layer point at the centre of pixel (i, j).
  format::Double2 pixel_centre(std::uint32_t i, std::uint32_t j) const;
  /// Layer units per pixel.
  double pixel_size() const { return 1.0 / scale_; }
  Size size() const { return size_; }
  bool wrap() const { return wrap_; }

 private:
  Size size_;
  bool wrap_ = false;
  double scale_ = 1, left_ = 0, top_ = 0;  // pixels per unit; the layer x at pixel 0, y at row 0
};

/// What a map shows. `polygons` or `points` (or both) must be set; `polygon_index` /
/// `point_index` answer the cells and heatmap modes for them.
struct MapContent {
  const PolygonLayerView* polygons = nullptr;
  const PointTableView* points = nullptr;
  const PolygonQueries* polygon_index = nullptr;
  const Point2Queries* point_index = nullptr;
};

/// Costs of a heatmap (node visits + primitive tests per pixel's query) and the cells drawn.
struct MapStats {
  double mean_cost = 0;
  std::uint32_t max_cost = 0, heat_scale = 0;
  std::uint64_t cells = 0;
};

/// The feature colour: a stable hash of the feature index into a 12-colour palette.
Rgb feature_colour(std::uint64_t feature);

/// Draws the map: polygons filled with the even-odd rule over every ring of a feature (so holes
/// stay open), later features over earlier ones, then outlines, points, cells; or the heatmap
/// under the outlines, with its legend. Heatmap queries run on up to `threads` threads;
/// the image never depends on the count. Throws std::invalid_argument when the mode needs an
/// index that `content` lacks.
Image draw_map(const MapContent& content, MapMode mode, Size size, unsigned threads,
               MapStats* stats = nullptr);

/// Whether the blob's input is a 2D polygon layer or point table (kiln render draws a map).
bool is_map_blob(const Blob& blob);

/// `kiln render` on a 2D blob: the map in `mode_name` (empty: "map") of size `size_text`, the
/// index for cells and heatmap the structure `accel` (empty: the first that answers the
/// layer's queries), written atomically to `out` as PNG; a summary line (or JSON) on stdout.
/// Returns the exit status; one line on stderr on any error.
int render_map_command(const Blob& blob, const std::string& out, const std::string& accel,
                       const std::string& mode_name, const std::string& size_text, unsigned threads,
                       bool json);

// --- Web-Mercator tiles (`kiln serve`'s GET /tiles; render_map.cpp, render_events_tile.cpp) ---

/// Side of a map tile in pixels.
inline constexpr std::uint32_t kTileSize = 256;
/// A tile z/x/y (y south); valid when z <= 30 and x, y < 2^z.
struct TileAddress {
  std::uint32_t z = 0, x = 0, y = 0;
  bool valid() const { return z <= 30 && x < (1ull << z) && y < (1ull << z); }
};

/// The tile of a polygon layer: features filled and outlined as in `kiln render`'s plain map,
/// in Web-Mercator pixels (latitudes clamped to +-85.0511), the sea colour elsewhere.
Image draw_polygon_tile(const PolygonLayerView& layer, TileAddress tile);

/// An image with transparency (RGBA8, row-major, top row first).
struct ImageRgba {
  std::uint32_t width = 0, height = 0;
  std::vector<std::uint8_t> rgba;
};
/// PNG bytes of an RGBA image.
std::vector<std::byte> encode_png_rgba(const ImageRgba& image);

/// The heatmap scale of `kiln render` on events: log2(1 + top) rounded, at least 1.
std::uint32_t event_levels(std::uint64_t top);
/// The colour of a cell holding `count` events on that scale (viridis, as kiln render).
Rgb event_colour(std::uint64_t count, std::uint32_t levels);

/// The heatmap tile of the selected events: the cube's counts at zoom min(z + 6, finest) (one
/// block of at least 4 x 4 pixels per cell; past the finest zoom the whole tile is its finest
/// cell), coloured by event_colour on `levels`, transparent where there are none. `selection`'s box
/// and tile are replaced by the tile's. Throws std::invalid_argument for an invalid address.
ImageRgba draw_event_tile(const EventQueries& cube, EventSelection selection, TileAddress tile,
                          std::uint32_t levels);

}  // namespace kiln::render
