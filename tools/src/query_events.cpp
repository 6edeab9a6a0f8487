// `kiln query` over event tables: each line of --in a JSON selection (box or tile, time, where)
// with the op's parameters (bin, zoom, k and by), each line of --out its answer with the snapped
// box and interval (docs/FORMAT.md, "Event queries").
#include "query_events.hpp"

#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

#include "kiln/compiler/event_table.hpp"
#include "kiln/runtime/atomic_file.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/nanocube.hpp"
#include "kiln/tools/structure_choice.hpp"

namespace kiln::cli {

namespace {

using nlohmann::json;

std::int64_t time_of(const json& value) {
  if (value.is_number_integer()) return value.get<std::int64_t>();
  if (value.is_string())
    if (const auto t = parse_event_time(value.get<std::string>())) return *t;
  throw std::invalid_argument("'time' holds " + value.dump() +
                              ", not an ISO 8601 time or Unix seconds");
}

EventSelection selection_of(const json& q) {
  EventSelection s;
  if (q.contains("box")) {
    const auto b = q.at("box").get<std::vector<double>>();
    if (b.size() != 4)
      throw std::invalid_argument("'box' needs [min_lon, min_lat, max_lon, max_lat]");
    s.box = format::Box2d{{b[0], b[1]}, {b[2], b[3]}};
  }
  if (q.contains("tile")) {
    const auto t = q.at("tile").get<std::vector<std::uint32_t>>();
    if (t.size() != 3) throw std::invalid_argument("'tile' needs [z, x, y]");
    s.tile = std::array<std::uint32_t, 3>{t[0], t[1], t[2]};
  }
  if (q.contains("time")) {
    const json& t = q.at("time");
    if (!t.is_array() || t.size() != 2) throw std::invalid_argument("'time' needs [start, end]");
    s.time = std::array<std::int64_t, 2>{time_of(t[0]), time_of(t[1])};
  }
  if (q.contains("where")) {
    if (!q.at("where").is_object()) throw std::invalid_argument("'where' needs an object");
    for (const auto& [name, labels] : q.at("where").items())
      s.where.emplace_back(name, labels.is_string()
                                     ? std::vector<std::string>{labels.get<std::string>()}
                                     : labels.get<std::vector<std::string>>());
  }
  return s;
}

json answer(const EventQueries& cube, const std::string& op, const json& q) {
  const EventSelection s = selection_of(q);
  json a = json::object();
  if (op == "count") {
    a["count"] = cube.count(s);
  } else if (op == "series") {
    const json& bin = q.value("bin", json("1d"));
    const std::int64_t width =
        bin.is_number_integer() ? bin.get<std::int64_t>() : parse_duration(bin.get<std::string>());
    json series = json::array();
    for (const auto& [t, n] : cube.series(s, width))
      series.push_back(json::array({format_event_time(t), n}));
    a["series"] = std::move(series);
  } else if (op == "tiles") {
    if (!q.contains("zoom")) throw std::invalid_argument("'tiles' needs \"zoom\"");
    json tiles = json::array();
    for (const EventTileCount& t : cube.tiles(s, q.at("zoom").get<std::uint32_t>()))
      tiles.push_back(json::array({t.z, t.x, t.y, t.count}));
    a["tiles"] = std::move(tiles);
  } else {  // topk
    if (!q.contains("by")) throw std::invalid_argument("'topk' needs \"by\"");
    json top = json::array();
    for (const EventLabelCount& l :
         cube.topk(s, q.at("by").get<std::string>(), q.value("k", std::size_t(10))))
      top.push_back(json::array({l.label, l.count}));
    a["topk"] = std::move(top);
  }
  const EventSnap snap = cube.snap(s);
  if (s.box || s.tile)
    a["box"] = json::array({snap.box.min.x, snap.box.min.y, snap.box.max.x, snap.box.max.y});
  if (s.time) a["time"] = json::array({format_event_time(snap.t0), format_event_time(snap.t1)});
  return a;
}

}  // namespace

bool is_event_op(const std::string& op) {
  return op == "count" || op == "series" || op == "tiles" || op == "topk";
}

int run_event_query(const std::string& blob_path, const std::string& accel, const std::string& op,
                    const std::string& in, const std::string& out) {
  try {
    const Blob blob = Blob::open_file(blob_path);
    const ChosenStructure chosen =
        choose_structure(blob, accel, &StructureView::events, "answer aggregate event queries");
    const EventQueries& cube = *chosen.view->events();
    std::ifstream input(in);
    if (!input) throw std::runtime_error(in + ": cannot read");
    std::string line, text;
    for (std::uint64_t number = 1; std::getline(input, line); ++number) {
      if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
      try {
        text += answer(cube, op, json::parse(line)).dump() + "\n";
      } catch (const std::exception& e) {
        throw std::runtime_error(in + ":" + std::to_string(number) + ": " + e.what());
      }
    }
    write_file_atomically(out, std::as_bytes(std::span<const char>(text)));
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "kiln query: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace kiln::cli
