// Heatmap tiles of event counts for `kiln serve`: the colours of `kiln render`'s event heatmap
// (render_events.cpp), one block per cube cell, on a transparent background so the polygon base
// layer shows through (encoded as PNG with alpha by render_png.cpp).
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "kiln/tools/render_map.hpp"

namespace kiln::render {

namespace {

void fill_block(ImageRgba& image, std::uint32_t x0, std::uint32_t y0, std::uint32_t side, Rgb c) {
  for (std::uint32_t y = y0; y < std::min(image.height, y0 + side); ++y)
    for (std::uint32_t x = x0; x < std::min(image.width, x0 + side); ++x) {
      std::uint8_t* p = &image.rgba[(std::size_t(y) * image.width + x) * 4];
      p[0] = c.r, p[1] = c.g, p[2] = c.b, p[3] = 255;
    }
}

}  // namespace

std::uint32_t event_levels(std::uint64_t top) {
  return std::max(1u, std::uint32_t(std::lround(std::log2(1.0 + double(top)))));
}

Rgb event_colour(std::uint64_t count, std::uint32_t levels) {
  const auto level = std::uint32_t(std::lround(std::log2(1.0 + double(count))));
  return heat_colour(std::max(level, 1u), levels);
}

ImageRgba draw_event_tile(const EventQueries& cube, EventSelection selection, TileAddress tile,
                          std::uint32_t levels) {
  if (!tile.valid()) throw std::invalid_argument("no such tile");
  ImageRgba image{kTileSize, kTileSize, std::vector<std::uint8_t>(kTileSize * kTileSize * 4, 0)};
  const std::uint32_t finest = cube.finest_level();
  selection.box.reset();
  if (tile.z > finest) {  // the whole tile is part of one finest cell
    const std::uint32_t up = tile.z - finest;
    selection.tile = std::array<std::uint32_t, 3>{finest, tile.x >> up, tile.y >> up};
    if (const std::uint64_t n = cube.count(selection))
      fill_block(image, 0, 0, kTileSize, event_colour(n, levels));
    return image;
  }
  // Cells 6 levels down are blocks of 4 x 4 pixels, so single places (airports) stay visible,
  // as in kiln render.
  const std::uint32_t zoom = std::min(tile.z + 6, finest);
  const std::uint32_t side = kTileSize >> (zoom - tile.z);
  selection.tile = std::array<std::uint32_t, 3>{tile.z, tile.x, tile.y};
  for (const EventTileCount& t : cube.tiles(selection, zoom)) {
    const std::uint32_t dx = t.x - (tile.x << (zoom - tile.z));
    const std::uint32_t dy = t.y - (tile.y << (zoom - tile.z));
    fill_block(image, dx * side, dy * side, side, event_colour(t.count, levels));
  }
  return image;
}

}  // namespace kiln::render
