// What `kiln serve` answers, without HTTP: POST /api/query bodies and GET /tiles requests in,
// status and bytes out. serve_server.cpp wires these to cpp-httplib; tests call them directly
// too. Limits are stated here and in docs/SERVE.md.
#pragma once

#include <chrono>
#include <cstddef>
#include <map>
#include <string>
#include <string_view>

#include "serve_catalog.hpp"

namespace kiln::serve {

/// The bounds every request is held to.
struct Limits {
  std::size_t max_request_bytes = 1 << 20;  ///< a request body (413 beyond)
  std::size_t max_queries = 64;             ///< query objects in one POST (413 beyond)
  /// Wall time of one request: a batch stops before its next query once this is spent (503).
  std::chrono::milliseconds max_time{2000};
  std::size_t max_answer_items = 100000;  ///< series bins or tiles in one answer (413 beyond)
};

/// An HTTP answer: status, body and its media type.
struct Response {
  int status = 200;
  std::string body;
  std::string type = "application/json";
};

/// {"error": message} with `status`.
Response error_response(int status, std::string_view message);

/// POST /api/query: `body` is one query object (-> its answer object) or an array of them (->
/// an array of answers, the first failure failing the request with its index in the message).
Response query_request(const Catalog& catalog, std::string_view body, const Limits& limits);

/// GET /tiles/{blob}/{z}/{x}/{y}.png with its query parameters: `time=START,END` and
/// `where=NAME:LABEL,LABEL` (repeatable) for an event blob's heatmap; a polygon layer's tile
/// otherwise. z, x and y as the path spells them (decimal digits).
Response tile_request(const Catalog& catalog, std::string_view blob, std::string_view z,
                      std::string_view x, std::string_view y,
                      const std::multimap<std::string, std::string>& params);

}  // namespace kiln::serve
