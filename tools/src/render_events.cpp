// The event heatmap: the cube's tile counts at the deepest zoom whose tiles over the view fit
// the image, one block of pixels per tile, coloured by log2(1 + count) on viridis.
#include "render_events.hpp"

#include <CLI/CLI.hpp>
#include <cmath>
#include <iostream>
#include <sstream>

#include "kiln/compiler/event_table.hpp"
#include "kiln/formats/nanocube.hpp"
#include "kiln/runtime/atomic_file.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/tools/render.hpp"
#include "kiln/tools/render_map.hpp"
#include "kiln/tools/structure_choice.hpp"

namespace kiln::cli {

namespace {

std::vector<std::string> split(const std::string& text, char separator) {
  std::vector<std::string> parts;
  std::stringstream in(text);
  for (std::string part; std::getline(in, part, separator);) parts.push_back(part);
  return parts;
}

EventSelection selection_of(const EventRenderArgs& args) {
  EventSelection s;
  if (!args.time.empty()) {
    const auto parts = split(args.time, ',');
    const auto t0 = parts.size() == 2 ? parse_event_time(parts[0]) : std::nullopt;
    const auto t1 = parts.size() == 2 ? parse_event_time(parts[1]) : std::nullopt;
    if (!t0 || !t1) throw std::invalid_argument("--time needs START,END (ISO 8601 or Unix s)");
    s.time = std::array<std::int64_t, 2>{*t0, *t1};
  }
  for (const std::string& w : args.where) {
    const auto eq = w.find('=');
    if (eq == std::string::npos) throw std::invalid_argument("--where needs NAME=LABEL[,LABEL]");
    s.where.emplace_back(w.substr(0, eq), split(w.substr(eq + 1), ','));
  }
  if (!args.box.empty()) {
    const auto parts = split(args.box, ',');
    if (parts.size() != 4)
      throw std::invalid_argument("--box needs min_lon,min_lat,max_lon,max_lat");
    s.box = format::Box2d{{std::stod(parts[0]), std::stod(parts[1])},
                          {std::stod(parts[2]), std::stod(parts[3])}};
  }
  return s;
}

// The view's tiles at zoom z: [x0, x1] x [y0, y1].
struct TileRange {
  std::uint32_t z, x0, x1, y0, y1;
  std::uint32_t width() const { return x1 - x0 + 1; }
  std::uint32_t height() const { return y1 - y0 + 1; }
};

TileRange view_range(const format::Box2d& b, std::uint32_t z) {
  return {z, format::mercator_cell_x(b.min.x, z), format::mercator_cell_x(b.max.x, z),
          format::mercator_cell_y(b.max.y, z), format::mercator_cell_y(b.min.y, z)};
}

// The deepest zoom (up to the cube's) whose tiles over the view fit the image.
TileRange fit(const format::Box2d& view, std::uint32_t max_level, render::Size size) {
  TileRange best = view_range(view, 0);
  for (std::uint32_t z = 1; z <= max_level; ++z) {
    const TileRange r = view_range(view, z);
    if (r.width() > size.width || r.height() > size.height) break;
    best = r;
  }
  return best;
}

render::Image draw(const std::vector<EventTileCount>& tiles, const TileRange& r,
                   std::uint32_t scale, std::uint32_t levels) {
  render::Image image(r.width() * scale, r.height() * scale, {24, 24, 32});
  for (const EventTileCount& t : tiles) {
    if (t.x < r.x0 || t.x > r.x1 || t.y < r.y0 || t.y > r.y1) continue;
    const render::Rgb c = render::event_colour(t.count, levels);
    for (std::uint32_t dy = 0; dy < scale; ++dy)
      for (std::uint32_t dx = 0; dx < scale; ++dx)
        image.at((t.x - r.x0) * scale + dx, (t.y - r.y0) * scale + dy) = c;
  }
  return image;
}

}  // namespace

void add_event_render_options(CLI::App* command, EventRenderArgs& args) {
  command->add_option("--time", args.time,
                      "Event tables: START,END (half-open; ISO 8601 or Unix s)");
  command->add_option("--where", args.where,
                      "Event tables: NAME=LABEL[,LABEL...] keeps those labels (repeatable)");
  command->add_option("--box", args.box, "Event tables: min_lon,min_lat,max_lon,max_lat to show");
}

int run_event_render(const Blob& blob, const std::string& accel, const std::string& out,
                     const std::string& size_text, const EventRenderArgs& args) {
  try {
    std::string error;
    const auto size = render::parse_size(size_text, error);
    if (!size) throw std::invalid_argument(error);
    const ChosenStructure chosen =
        choose_structure(blob, accel, &StructureView::events, "answer event queries");
    const auto& cube = *chosen.view->events();
    const EventSelection selection = selection_of(args);
    const std::uint32_t max_level = cube.finest_level();
    const format::Box2d box = selection.box ? *selection.box : blob.input().bounds2;
    // Tiles of at least 4 x 4 pixels, so single places (airports) stay visible.
    const TileRange range =
        fit(box, max_level, {std::max(1u, size->width / 4), std::max(1u, size->height / 4)});
    EventSelection in_view = selection;
    if (!in_view.box) in_view.box = box;
    const auto tiles = cube.tiles(in_view, range.z);
    std::uint64_t top = 1, total = 0;
    for (const auto& t : tiles) top = std::max(top, t.count), total += t.count;
    const auto levels = render::event_levels(top);
    const std::uint32_t scale =
        std::max(1u, std::min(size->width / range.width(), size->height / range.height()));
    render::Image image = draw(tiles, range, scale, levels);
    render::draw_legend(image, levels, false, "events per tile, log2(1 + n)");
    write_file_atomically(out, render::encode_png(image));
    std::cout << "wrote " << out << ": " << image.width << "x" << image.height << ", zoom "
              << range.z << ", " << tiles.size() << " tiles, " << total << " events, max " << top
              << " per tile\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "kiln render: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace kiln::cli
