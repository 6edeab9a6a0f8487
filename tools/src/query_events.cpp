// Event queries as JSON: each object a selection (box or tile, time, where) with the op's
// parameters (bin, zoom, k and by); its answer carries the snapped box and interval
// (docs/FORMAT.md, "Event queries"). Shared by `kiln query` and `kiln serve`.
#include "query_events.hpp"

#include <cmath>
#include <stdexcept>

#include "kiln/compiler/event_table.hpp"
#include "kiln/runtime/nanocube.hpp"
#include "kiln/tools/query_json.hpp"

namespace kiln::cli {

namespace {

using nlohmann::json;

// The fields any event op reads (a count line may carry a topk's "by": it is ignored).
constexpr std::string_view kEventFields[] = {"box", "tile", "time", "where",
                                             "bin", "zoom", "k",    "by"};

std::int64_t time_of(const json& value) {
  if (value.is_number_integer()) return value.get<std::int64_t>();
  if (value.is_string())
    if (const auto t = parse_event_time(value.get<std::string>())) return *t;
  throw QueryError("'time' holds " + value.dump() + ", not an ISO 8601 time or Unix seconds");
}

std::uint32_t unsigned_of(const json& value, std::string_view field) {
  if (!value.is_number_unsigned() || value.get<std::uint64_t>() > 0xFFFFFFFFu)
    throw QueryError("'" + std::string(field) + "' holds " + value.dump() +
                     ", not a whole number >= 0");
  return value.get<std::uint32_t>();
}

format::Box2d box_of(const json& value) {
  if (!value.is_array() || value.size() != 4)
    throw QueryError("'box' needs [min_lon, min_lat, max_lon, max_lat]");
  double c[4];
  for (int k = 0; k < 4; ++k) {
    if (!value[k].is_number())
      throw QueryError("'box' holds " + value[k].dump() + ", not a number");
    c[k] = value[k].get<double>();
  }
  return {{c[0], c[1]}, {c[2], c[3]}};
}

std::vector<std::string> labels_of(const std::string& name, const json& labels) {
  if (labels.is_string()) return {labels.get<std::string>()};
  if (labels.is_array()) {
    std::vector<std::string> out;
    for (const json& l : labels) {
      if (!l.is_string()) break;
      out.push_back(l.get<std::string>());
    }
    if (out.size() == labels.size()) return out;
  }
  throw QueryError("'where': '" + name + "' needs a label or a list of labels");
}

void check_fields(const json& q) {
  if (!q.is_object()) throw QueryError("a query must be a JSON object, not " + q.dump());
  for (const auto& [name, value] : q.items()) {
    bool known = name == "op" || name == "blob" || name == "structure";
    for (const auto field : kEventFields) known = known || name == field;
    if (!known) throw QueryError("unknown field '" + name + "'");
  }
}

json series_answer(const EventQueries& cube, const EventSelection& s, std::int64_t width) {
  json series = json::array();
  for (const auto& [t, n] : cube.series(s, width))
    series.push_back(json::array({format_event_time(t), n}));
  return series;
}

json series_of(const EventQueries& cube, const EventSelection& s, const json& q,
               std::size_t max_bins) {
  const json& bin = q.value("bin", json("1d"));
  std::int64_t width = 0;
  if (bin.is_number_integer())
    width = bin.get<std::int64_t>();
  else if (bin.is_string())
    width = parse_duration(bin.get<std::string>());
  else
    throw QueryError("'bin' holds " + bin.dump() + ", not a duration (\"1d\", \"6h\", seconds)");
  if (max_bins > 0 && width > 0) {  // the bins the answer would list, before counting them
    const EventSnap snap = cube.snap(s);
    if (snap.t1 <= snap.t0) return series_answer(cube, s, width);
    const std::uint64_t bins =
        (std::uint64_t(snap.t1 - snap.t0) + std::uint64_t(width) - 1) / std::uint64_t(width);
    if (bins > max_bins)
      throw QueryTooLarge("the series would hold " + std::to_string(bins) + " bins, more than " +
                          std::to_string(max_bins) + ": ask for a shorter interval or wider bins");
  }
  return series_answer(cube, s, width);
}

}  // namespace

EventSelection event_selection_of(const json& q) {
  check_fields(q);
  EventSelection s;
  if (q.contains("box")) s.box = box_of(q.at("box"));
  if (q.contains("tile")) {
    const json& t = q.at("tile");
    if (!t.is_array() || t.size() != 3) throw QueryError("'tile' needs [z, x, y]");
    s.tile = std::array<std::uint32_t, 3>{unsigned_of(t[0], "tile"), unsigned_of(t[1], "tile"),
                                          unsigned_of(t[2], "tile")};
  }
  if (q.contains("time")) {
    const json& t = q.at("time");
    if (!t.is_array() || t.size() != 2) throw QueryError("'time' needs [start, end]");
    s.time = std::array<std::int64_t, 2>{time_of(t[0]), time_of(t[1])};
  }
  if (q.contains("where")) {
    if (!q.at("where").is_object()) throw QueryError("'where' needs an object");
    for (const auto& [name, labels] : q.at("where").items())
      s.where.emplace_back(name, labels_of(name, labels));
  }
  return s;
}

json answer_event_json(const EventQueries& cube, std::string_view op, const json& q,
                       std::size_t max_series_bins) {
  const EventSelection s = event_selection_of(q);
  json a = json::object();
  if (op == "count") {
    a["count"] = cube.count(s);
  } else if (op == "series") {
    a["series"] = series_of(cube, s, q, max_series_bins);
  } else if (op == "tiles") {
    if (!q.contains("zoom")) throw QueryError("'tiles' needs \"zoom\"");
    json tiles = json::array();
    for (const EventTileCount& t : cube.tiles(s, unsigned_of(q.at("zoom"), "zoom")))
      tiles.push_back(json::array({t.z, t.x, t.y, t.count}));
    a["tiles"] = std::move(tiles);
  } else {  // topk
    if (!q.contains("by")) throw QueryError("'topk' needs \"by\"");
    if (!q.at("by").is_string()) throw QueryError("'by' needs a category name");
    const std::size_t k = q.contains("k") ? unsigned_of(q.at("k"), "k") : 10;
    json top = json::array();
    for (const EventLabelCount& l : cube.topk(s, q.at("by").get<std::string>(), k))
      top.push_back(json::array({l.label, l.count}));
    a["topk"] = std::move(top);
  }
  const EventSnap snap = cube.snap(s);
  if (s.box || s.tile)
    a["box"] = json::array({snap.box.min.x, snap.box.min.y, snap.box.max.x, snap.box.max.y});
  if (s.time) a["time"] = json::array({format_event_time(snap.t0), format_event_time(snap.t1)});
  return a;
}

bool is_event_op(const std::string& op) {
  return op == "count" || op == "series" || op == "tiles" || op == "topk";
}

}  // namespace kiln::cli
