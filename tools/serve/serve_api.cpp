// The JSON API and the tiles: requests parsed and refused with a status that says whose fault it
// is (400 the request's, 404 a name that is not served, 413 over a limit, 503 out of time), and
// every answer made by answer_json_query, the code path of `kiln query`.
#include "serve_api.hpp"

#include <charconv>
#include <sstream>

#include "../src/query_events.hpp"
#include "kiln/tools/query_json.hpp"
#include "kiln/tools/render_map.hpp"

namespace kiln::serve {

namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

// A refusal on its way to the response: status and message.
struct Refusal {
  int status;
  std::string message;
};

std::string served_names(const Catalog& catalog) {
  std::string names;
  for (const ServedBlob& b : catalog.blobs()) names += (names.empty() ? "" : ", ") + b.name;
  return names;
}

const ServedBlob& blob_of(const Catalog& catalog, const json& q) {
  std::string name;
  if (q.contains("blob")) {
    if (!q.at("blob").is_string()) throw Refusal{400, "'blob' needs a name"};
    name = q.at("blob").get<std::string>();
  } else if (catalog.blobs().size() != 1) {
    throw Refusal{400, "'blob' is needed: " + std::to_string(catalog.blobs().size()) +
                           " blobs are served (" + served_names(catalog) + ")"};
  }
  if (const ServedBlob* b = catalog.find(name)) return *b;
  throw Refusal{404, "no blob named '" + name + "' (served: " + served_names(catalog) + ")"};
}

std::size_t answer_items(const json& a) {
  std::size_t n = 0;
  for (const char* key : {"series", "tiles"})
    if (a.contains(key)) n += a.at(key).size();
  return n;
}

json answer_one(const Catalog& catalog, const json& q, const Limits& limits) {
  if (!q.is_object()) throw Refusal{400, "a query must be a JSON object, not " + q.dump()};
  if (!q.contains("op") || !q.at("op").is_string())
    throw Refusal{400,
                  "'op' is needed: count, series, tiles, topk, polygon, polygons-in-box, "
                  "range, knn2d or radius2d"};
  const std::string op = q.at("op").get<std::string>();
  if (!is_json_op(op)) throw Refusal{400, "unknown op '" + op + "'"};
  const ServedBlob& blob = blob_of(catalog, q);
  std::string structure;
  if (q.contains("structure")) {
    if (!q.at("structure").is_string()) throw Refusal{400, "'structure' needs a name"};
    structure = q.at("structure").get<std::string>();
  }
  const StructureView* view = blob.structure(structure, op);
  if (!view)
    throw Refusal{404, structure.empty()
                           ? "blob '" + blob.name + "' holds no structure that can " +
                                 std::string(op_ability(op))
                           : "blob '" + blob.name + "' holds no structure '" + structure + "'"};
  json a;
  try {
    a = answer_json_query(*blob.blob, *view, op, q, limits.max_answer_items);
  } catch (const std::invalid_argument& e) {  // QueryError and the cube's bad values
    throw Refusal{400, e.what()};
  } catch (const QueryTooLarge& e) {
    throw Refusal{413, e.what()};
  }
  if (answer_items(a) > limits.max_answer_items)
    throw Refusal{413, "the answer holds " + std::to_string(answer_items(a)) +
                           " series bins or tiles, more than " +
                           std::to_string(limits.max_answer_items) +
                           ": ask for a smaller box, a deeper tile or wider bins"};
  return a;
}

json answer_body(const Catalog& catalog, std::string_view body, const Limits& limits) {
  if (body.size() > limits.max_request_bytes)
    throw Refusal{413, "the request holds " + std::to_string(body.size()) + " bytes, more than " +
                           std::to_string(limits.max_request_bytes)};
  json request;
  try {
    request = json::parse(body);
  } catch (const json::parse_error& e) {
    throw Refusal{400, std::string("malformed JSON: ") + e.what()};
  }
  if (!request.is_array()) return answer_one(catalog, request, limits);
  if (request.size() > limits.max_queries)
    throw Refusal{413, std::to_string(request.size()) + " queries in one request, more than " +
                           std::to_string(limits.max_queries)};
  const auto start = Clock::now();
  json answers = json::array();
  for (std::size_t i = 0; i < request.size(); ++i) {
    if (Clock::now() - start > limits.max_time)
      throw Refusal{503, "the request ran past its " + std::to_string(limits.max_time.count()) +
                             " ms before query " + std::to_string(i)};
    try {
      answers.push_back(answer_one(catalog, request[i], limits));
    } catch (Refusal& r) {
      r.message = "query " + std::to_string(i) + ": " + r.message;
      throw;
    }
  }
  return answers;
}

bool parse_number(std::string_view text, std::uint32_t& value) {
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  return !text.empty() && error == std::errc() && end == text.data() + text.size();
}

// time=START,END and where=NAME:LABEL,LABEL as the fields of an event query object.
json selection_params(const std::multimap<std::string, std::string>& params) {
  json q = json::object();
  for (const auto& [key, value] : params) {
    if (key == "time") {
      const auto comma = value.find(',');
      if (comma == std::string::npos) throw Refusal{400, "'time' needs START,END"};
      auto part = [](const std::string& t) {
        std::int64_t n = 0;
        const auto [end, error] = std::from_chars(t.data(), t.data() + t.size(), n);
        return error == std::errc() && end == t.data() + t.size() ? json(n) : json(t);
      };
      q["time"] = json::array({part(value.substr(0, comma)), part(value.substr(comma + 1))});
    } else if (key == "where") {
      const auto colon = value.find(':');
      if (colon == std::string::npos) throw Refusal{400, "'where' needs NAME:LABEL[,LABEL...]"};
      json labels = json::array();
      std::stringstream in(value.substr(colon + 1));
      for (std::string label; std::getline(in, label, ',');) labels.push_back(label);
      q["where"][value.substr(0, colon)] = std::move(labels);
    } else {
      throw Refusal{400, "unknown parameter '" + key + "' (time, where)"};
    }
  }
  return q;
}

Response event_tile(const EventQueries& cube, render::TileAddress tile,
                    const std::multimap<std::string, std::string>& params) {
  EventSelection selection;
  try {
    selection = cli::event_selection_of(selection_params(params));
    // One colour scale for every tile of a selection: the selection's whole count.
    const std::uint32_t levels = render::event_levels(cube.count(selection));
    const auto png =
        render::encode_png_rgba(render::draw_event_tile(cube, selection, tile, levels));
    return {200, std::string(reinterpret_cast<const char*>(png.data()), png.size()), "image/png"};
  } catch (const std::invalid_argument& e) {
    throw Refusal{400, e.what()};
  }
}

}  // namespace

Response error_response(int status, std::string_view message) {
  return {status, json{{"error", message}}.dump(-1, ' ', false, json::error_handler_t::replace)};
}

Response query_request(const Catalog& catalog, std::string_view body, const Limits& limits) {
  try {
    return {
        200,
        answer_body(catalog, body, limits).dump(-1, ' ', false, json::error_handler_t::replace)};
  } catch (const Refusal& r) {
    return error_response(r.status, r.message);
  }
}

Response tile_request(const Catalog& catalog, std::string_view name, std::string_view z,
                      std::string_view x, std::string_view y,
                      const std::multimap<std::string, std::string>& params) {
  try {
    const ServedBlob* blob = catalog.find(name);
    if (!blob || name.empty()) throw Refusal{404, "no blob named '" + std::string(name) + "'"};
    render::TileAddress tile;
    if (!parse_number(z, tile.z) || !parse_number(x, tile.x) || !parse_number(y, tile.y) ||
        !tile.valid())
      throw Refusal{404, "no tile " + std::string(z) + "/" + std::string(x) + "/" + std::string(y) +
                             " (z <= 30, x and y < 2^z)"};
    if (const StructureView* view = blob->structure("", "count"))
      return event_tile(*view->events(), tile, params);
    if (blob->blob->input().kind != InputKind::kPolygons2)
      throw Refusal{404, "blob '" + blob->name +
                             "' has no tiles (an event table with a "
                             "nanocube or a polygon layer has)"};
    if (!params.empty()) throw Refusal{400, "a polygon layer's tiles take no parameters"};
    const auto png =
        render::encode_png(render::draw_polygon_tile(blob->blob->polygon_layer(), tile));
    return {200, std::string(reinterpret_cast<const char*>(png.data()), png.size()), "image/png"};
  } catch (const Refusal& r) {
    return error_response(r.status, r.message);
  }
}

}  // namespace kiln::serve
