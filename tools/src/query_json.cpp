// One JSON query answered by the capability its op needs: events (query_events.cpp), point in
// polygon and features in a box (polygon layers), range and neighbours (2D point tables). Both
// `kiln query` (JSON lines) and `kiln serve` (POST /api/query) call answer_json_query.
#include "kiln/tools/query_json.hpp"

#include <cmath>
#include <fstream>
#include <iostream>

#include "kiln/runtime/atomic_file.hpp"
#include "kiln/tools/structure_choice.hpp"
#include "query_events.hpp"
#include "query_points2d.hpp"

namespace kiln {

namespace {

using nlohmann::json;

void check_fields(const json& q, std::initializer_list<std::string_view> fields) {
  if (!q.is_object()) throw QueryError("a query must be a JSON object, not " + q.dump());
  for (const auto& [name, value] : q.items()) {
    bool known = name == "op" || name == "blob" || name == "structure";
    for (const auto field : fields) known = known || name == field;
    if (!known) throw QueryError("unknown field '" + name + "'");
  }
}

const json& required(const json& q, const char* field, std::string_view op) {
  if (!q.contains(field))
    throw QueryError("'" + std::string(op) + "' needs \"" + std::string(field) + "\"");
  return q.at(field);
}

double number_of(const json& v, std::string_view field) {
  if (!v.is_number() || !std::isfinite(v.get<double>()))
    throw QueryError("'" + std::string(field) + "' holds " + v.dump() + ", not a finite number");
  return v.get<double>();
}

format::Double2 point_of(const json& v, std::string_view field) {
  if (!v.is_array() || v.size() != 2)
    throw QueryError("'" + std::string(field) + "' needs [x, y] (longitude, latitude)");
  return {number_of(v[0], field), number_of(v[1], field)};
}

format::Box2d box_of(const json& v) {
  if (!v.is_array() || v.size() != 4) throw QueryError("'box' needs [min_x, min_y, max_x, max_y]");
  return {{number_of(v[0], "box"), number_of(v[1], "box")},
          {number_of(v[2], "box"), number_of(v[3], "box")}};
}

// A feature of the layer as the answers name it: index, id and name (empty when absent).
json feature_of(const PolygonLayerView& layer, std::uint32_t f) {
  if (f == PolygonQueries::kNone) return nullptr;
  return {{"index", f},
          {"id", layer.ids.empty() ? std::string() : std::string(layer.ids[f])},
          {"name", layer.names.empty() ? std::string() : std::string(layer.names[f])}};
}

// polygon: {"points": [[x, y], ...], "all": false} -> {"features": [feature or null, ...]};
// with "all": a list of every containing feature per point. polygons-in-box: {"box": [...]} ->
// {"features": [feature, ...]}, ascending.
json answer_polygon(const PolygonQueries& q, const PolygonLayerView& layer, std::string_view op,
                    const json& query) {
  json features = json::array();
  if (op == "polygons-in-box") {
    check_fields(query, {"box"});
    std::vector<std::uint32_t> found;
    q.features_in_box(box_of(required(query, "box", op)), found);
    for (const auto f : found) features.push_back(feature_of(layer, f));
    return {{"features", std::move(features)}};
  }
  check_fields(query, {"points", "all"});
  const json& points = required(query, "points", op);
  if (!points.is_array()) throw QueryError("'points' needs [[x, y], ...]");
  if (points.size() > kMaxQueryPoints)
    throw QueryError("'points' holds " + std::to_string(points.size()) + " points, more than " +
                     std::to_string(kMaxQueryPoints));
  const json& all = query.value("all", json(false));
  if (!all.is_boolean()) throw QueryError("'all' needs true or false");
  if (!all.get<bool>()) {
    std::vector<format::Double2> xy;
    xy.reserve(points.size());
    for (const json& p : points) xy.push_back(point_of(p, "points"));
    std::vector<std::uint32_t> found(xy.size());
    q.locate_many(xy, found, 1);  // one request, one thread: requests run side by side
    for (const auto f : found) features.push_back(feature_of(layer, f));
    return {{"features", std::move(features)}};
  }
  for (const json& p : points) {
    std::vector<std::uint32_t> found;
    q.locate_all(point_of(p, "points"), found);
    json list = json::array();
    for (const auto f : found) list.push_back(feature_of(layer, f));
    features.push_back(std::move(list));
  }
  return {{"features", std::move(features)}};
}

// range: {"box"} -> {"rows": [...]}; knn2d: {"point", "k"}, radius2d: {"point", "radius"} ->
// {"neighbors": [[row, distance], ...]}: rows of the table, as the CSV answers give them.
json answer_points2(const Point2Queries& q, const PointTableView& table, std::string_view op,
                    const json& query) {
  const cli::RowOf row_of{table.feature_points};
  if (op == "range") {
    check_fields(query, {"box"});
    std::vector<std::uint32_t> found;
    q.range(box_of(required(query, "box", op)), found);
    json rows = json::array();
    std::uint64_t last = ~std::uint64_t{0};
    for (const auto point : found)
      if (const std::uint64_t row = row_of(point); row != last) rows.push_back(last = row);
    return {{"rows", std::move(rows)}};
  }
  check_fields(query, {"point", op == "knn2d" ? "k" : "radius"});
  const format::Double2 p = point_of(required(query, "point", op), "point");
  std::vector<Neighbor2> found;
  if (op == "knn2d") {
    const json& k = query.value("k", json(1));
    if (!k.is_number_unsigned() || k.get<std::uint64_t>() < 1 ||
        k.get<std::uint64_t>() > kMaxQueryK)
      throw QueryError("'k' holds " + k.dump() + ", not a whole number in 1.." +
                       std::to_string(kMaxQueryK));
    found.resize(k.get<std::size_t>());
    found.resize(q.nearest(p, found));
  } else {
    const double radius = number_of(required(query, "radius", op), "radius");
    if (radius < 0) throw QueryError("'radius' must be >= 0");
    q.within_radius(p, radius, found);
  }
  json neighbors = json::array();
  for (const Neighbor2& n : found)
    neighbors.push_back(json::array({row_of(n.index), std::sqrt(n.distance_squared)}));
  return {{"neighbors", std::move(neighbors)}};
}

}  // namespace

bool is_json_op(std::string_view op) {
  return cli::is_event_op(std::string(op)) || op == "polygon" || op == "polygons-in-box" ||
         op == "range" || op == "knn2d" || op == "radius2d";
}

bool view_answers(const StructureView& view, std::string_view op) {
  if (cli::is_event_op(std::string(op))) return view.events() != nullptr;
  if (op == "polygon" || op == "polygons-in-box") return view.polygons() != nullptr;
  if (op == "range" || op == "knn2d" || op == "radius2d") return view.points2() != nullptr;
  return false;
}

std::string_view op_ability(std::string_view op) {
  if (cli::is_event_op(std::string(op))) return "answer aggregate event queries";
  if (op == "polygon" || op == "polygons-in-box") return "answer point-in-polygon queries";
  return "answer 2D point range and neighbour queries";
}

json answer_json_query(const Blob& blob, const StructureView& view, std::string_view op,
                       const json& query, std::size_t max_series_bins) {
  if (!view_answers(view, op))
    throw QueryError("the structure cannot " + std::string(op_ability(op)));
  if (view.events()) return cli::answer_event_json(*view.events(), op, query, max_series_bins);
  if (view.polygons() && (op == "polygon" || op == "polygons-in-box"))
    return answer_polygon(*view.polygons(), blob.polygon_layer(), op, query);
  return answer_points2(*view.points2(), blob.point_table(), op, query);
}

namespace cli {

namespace {

// The first structure answering `op` (or the one `accel` names), through the capability getter.
ChosenStructure choose_for_op(const Blob& blob, const std::string& accel, const std::string& op) {
  const std::string ability(op_ability(op));
  if (is_event_op(op)) return choose_structure(blob, accel, &StructureView::events, ability);
  if (op == "polygon" || op == "polygons-in-box")
    return choose_structure(blob, accel, &StructureView::polygons, ability);
  return choose_structure(blob, accel, &StructureView::points2, ability);
}

}  // namespace

int run_json_query(const std::string& blob_path, const std::string& accel, const std::string& op,
                   const std::string& in, const std::string& out) {
  try {
    const Blob blob = Blob::open_file(blob_path);
    const ChosenStructure chosen = choose_for_op(blob, accel, op);
    std::ifstream input(in);
    if (!input) throw std::runtime_error(in + ": cannot read");
    std::string line, text;
    for (std::uint64_t number = 1; std::getline(input, line); ++number) {
      if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
      try {
        text += answer_json_query(blob, *chosen.view, op, json::parse(line)).dump() + "\n";
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

}  // namespace cli

}  // namespace kiln
