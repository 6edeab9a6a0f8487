// What the nanocube and its reference share (snapping a selection, durations, top-k order) and
// the reference itself: every query answered by scanning the mapped event table.
#include <algorithm>
#include <charconv>
#include <map>
#include <stdexcept>
#include <string>

#include "kiln/runtime/nanocube.hpp"

namespace kiln {

namespace {

constexpr std::int64_t kTimeClamp = std::int64_t(1) << 61;

std::int64_t floor_div(std::int64_t a, std::int64_t b) {
  return a / b - ((a % b != 0) && ((a < 0) != (b < 0)));
}

void intersect(ResolvedSelection& r, std::uint64_t x0, std::uint64_t x1, std::uint64_t y0,
               std::uint64_t y1) {
  r.x0 = std::uint32_t(std::max<std::uint64_t>(r.x0, x0));
  r.x1 = std::uint32_t(std::min<std::uint64_t>(r.x1, x1));
  r.y0 = std::uint32_t(std::max<std::uint64_t>(r.y0, y0));
  r.y1 = std::uint32_t(std::min<std::uint64_t>(r.y1, y1));
  if (r.x0 > r.x1 || r.y0 > r.y1) r.empty = true;
}

void resolve_space(const EventSelection& s, const EventGrid& grid, ResolvedSelection& r) {
  const std::uint32_t level = grid.max_level;
  const std::uint64_t n = std::uint64_t(1) << level;
  r.x0 = 0, r.y0 = 0, r.x1 = std::uint32_t(n - 1), r.y1 = std::uint32_t(n - 1);
  if (s.box) {
    const format::Box2d& b = *s.box;
    if (!(b.min.x <= b.max.x) || !(b.min.y <= b.max.y)) r.empty = true;
    intersect(r, format::mercator_cell_x(b.min.x, level), format::mercator_cell_x(b.max.x, level),
              format::mercator_cell_y(b.max.y, level), format::mercator_cell_y(b.min.y, level));
  }
  if (s.tile) {
    const auto [z, x, y] = *s.tile;
    if (z > level)
      throw std::invalid_argument("tile zoom " + std::to_string(z) +
                                  " is past the cube's finest level " + std::to_string(level));
    if (x >= (std::uint64_t(1) << z) || y >= (std::uint64_t(1) << z))
      throw std::invalid_argument("tile " + std::to_string(x) + "," + std::to_string(y) +
                                  " is outside zoom " + std::to_string(z));
    const std::uint32_t shift = level - z;
    intersect(r, std::uint64_t(x) << shift, ((std::uint64_t(x) + 1) << shift) - 1,
              std::uint64_t(y) << shift, ((std::uint64_t(y) + 1) << shift) - 1);
  }
  if (!r.empty)
    r.snap.box = {{format::mercator_lon(r.x0, level), format::mercator_lat(r.y1 + 1ull, level)},
                  {format::mercator_lon(r.x1 + 1ull, level), format::mercator_lat(r.y0, level)}};
}

}  // namespace

ResolvedSelection resolve_event_selection(const EventSelection& s, const EventTableView& table,
                                          const EventGrid& grid) {
  ResolvedSelection r;
  resolve_space(s, grid, r);
  const std::int64_t bin = grid.time_bin, origin = grid.time_origin;
  r.b0 = 0, r.b1 = grid.bin_count;
  if (s.time) {
    const std::int64_t t0 = std::clamp((*s.time)[0], -kTimeClamp, kTimeClamp);
    const std::int64_t t1 = std::clamp((*s.time)[1], -kTimeClamp, kTimeClamp);
    r.b0 = floor_div(t0 - origin, bin);
    r.b1 = std::max(r.b0, -floor_div(origin - t1, bin));  // ceil
  }
  r.snap.t0 = origin + r.b0 * bin, r.snap.t1 = origin + r.b1 * bin;
  r.allowed.resize(table.categories.size());
  for (const auto& [name, labels] : s.where) {
    const auto c = table.category(name);
    if (!c) throw std::invalid_argument("no category '" + name + "' in the event table");
    std::vector<char> mask(table.categories[*c].label_count, 0);
    for (const std::string& label : labels)
      if (const auto code = table.code_of(*c, label)) mask[*code] = 1;
    if (!r.allowed[*c].empty())  // named twice: both must hold
      for (std::size_t i = 0; i < mask.size(); ++i) mask[i] &= r.allowed[*c][i];
    r.allowed[*c] = std::move(mask);
  }
  return r;
}

std::int64_t parse_duration(std::string_view text) {
  std::int64_t value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  const std::string_view unit(end, std::size_t(text.data() + text.size() - end));
  static const std::map<std::string_view, std::int64_t> kUnits = {
      {"", 1}, {"s", 1}, {"m", 60}, {"min", 60}, {"h", 3600}, {"d", 86400}, {"w", 604800}};
  const auto it = kUnits.find(unit);
  if (ec != std::errc() || it == kUnits.end() || value <= 0 || value > (std::int64_t(1) << 40))
    throw std::invalid_argument("'" + std::string(text) +
                                "' is not a duration (e.g. 30s, 15m, 1h, 1d, 1w)");
  return value * it->second;
}

std::vector<EventLabelCount> top_labels(std::vector<EventLabelCount> all, std::size_t k) {
  std::erase_if(all, [](const EventLabelCount& l) { return l.count == 0; });
  std::sort(all.begin(), all.end(), [](const EventLabelCount& a, const EventLabelCount& b) {
    return a.count != b.count ? a.count > b.count : a.label < b.label;
  });
  if (all.size() > k) all.resize(k);
  return all;
}

std::vector<std::pair<std::int64_t, std::uint64_t>> empty_series(const EventGrid& grid,
                                                                 const ResolvedSelection& r,
                                                                 std::int64_t bin_seconds) {
  if (bin_seconds <= 0 || bin_seconds % grid.time_bin != 0)
    throw std::invalid_argument("series bin of " + std::to_string(bin_seconds) +
                                " s is not a multiple of the cube's time bin (" +
                                std::to_string(grid.time_bin) + " s)");
  const std::int64_t per = bin_seconds / grid.time_bin, bins = (r.b1 - r.b0 + per - 1) / per;
  if (bins > 10'000'000) throw std::invalid_argument("a series of more than 10^7 bins");
  std::vector<std::pair<std::int64_t, std::uint64_t>> out(std::size_t(bins), {0, 0});
  for (std::int64_t i = 0; i < bins; ++i) out[std::size_t(i)].first = r.snap.t0 + i * bin_seconds;
  return out;
}

EventScan::EventScan(EventTableView table, EventGrid grid) : table_(std::move(table)), grid_(grid) {
  cell_x_.resize(table_.rows()), cell_y_.resize(table_.rows());
  for (std::size_t i = 0; i < table_.rows(); ++i) {
    cell_x_[i] = format::mercator_cell_x(table_.points[i].x, grid_.max_level);
    cell_y_[i] = format::mercator_cell_y(table_.points[i].y, grid_.max_level);
  }
}

template <class F>
void EventScan::scan(const ResolvedSelection& r, F&& f) const {
  if (r.empty) return;
  for (std::size_t i = 0; i < table_.rows(); ++i) {
    const std::int64_t bin = floor_div(table_.times[i] - grid_.time_origin, grid_.time_bin);
    if (bin < r.b0 || bin >= r.b1) continue;
    const std::uint32_t x = cell_x_[i], y = cell_y_[i];
    if (x < r.x0 || x > r.x1 || y < r.y0 || y > r.y1) continue;
    bool keep = true;
    for (std::size_t c = 0; c < r.allowed.size() && keep; ++c)
      keep = r.allowed[c].empty() || r.allowed[c][table_.codes[c * table_.rows() + i]];
    if (keep) f(i, x, y, bin);
  }
}

EventSnap EventScan::snap(const EventSelection& s) const {
  return resolve_event_selection(s, table_, grid_).snap;
}

std::uint64_t EventScan::count(const EventSelection& s) const {
  std::uint64_t n = 0;
  scan(resolve_event_selection(s, table_, grid_), [&](auto...) { ++n; });
  return n;
}

std::vector<std::pair<std::int64_t, std::uint64_t>> EventScan::series(const EventSelection& s,
                                                                      std::int64_t width) const {
  const ResolvedSelection r = resolve_event_selection(s, table_, grid_);
  auto out = empty_series(grid_, r, width);
  const std::int64_t per = width / grid_.time_bin;
  scan(r, [&](std::size_t, std::uint32_t, std::uint32_t, std::int64_t bin) {
    ++out[std::size_t((bin - r.b0) / per)].second;
  });
  return out;
}

std::vector<EventTileCount> EventScan::tiles(const EventSelection& s, std::uint32_t zoom) const {
  if (zoom > grid_.max_level)
    throw std::invalid_argument("zoom " + std::to_string(zoom) +
                                " is past the cube's finest level " +
                                std::to_string(grid_.max_level));
  const std::uint32_t shift = grid_.max_level - zoom;
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint64_t> counts;
  scan(resolve_event_selection(s, table_, grid_),
       [&](std::size_t, std::uint32_t x, std::uint32_t y, std::int64_t) {
         ++counts[{x >> shift, y >> shift}];
       });
  std::vector<EventTileCount> out;
  for (const auto& [xy, n] : counts) out.push_back({zoom, xy.first, xy.second, n});
  return out;
}

std::vector<EventLabelCount> EventScan::topk(const EventSelection& s, std::string_view by,
                                             std::size_t k) const {
  const auto c = table_.category(by);
  if (!c) throw std::invalid_argument("no category '" + std::string(by) + "' in the event table");
  std::vector<std::uint64_t> counts(table_.categories[*c].label_count, 0);
  const auto codes = table_.category_codes(*c);
  scan(resolve_event_selection(s, table_, grid_),
       [&](std::size_t i, std::uint32_t, std::uint32_t, std::int64_t) { ++counts[codes[i]]; });
  std::vector<EventLabelCount> all;
  for (std::uint32_t i = 0; i < counts.size(); ++i)
    all.push_back({std::string(table_.label(*c, i)), counts[i]});
  return top_labels(std::move(all), k);
}

}  // namespace kiln
