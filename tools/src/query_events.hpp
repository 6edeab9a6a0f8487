// `kiln query --op count|series|tiles|topk` (issue 18): JSON lines in, JSON lines out, answered
// by the blob's EventQueries structure (the nanocube).
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

#include "kiln/runtime/capabilities.hpp"

namespace kiln::cli {

bool is_event_op(const std::string& op);

/// The selection of an event query object (box, tile, time, where); throws QueryError naming
/// the bad field.
EventSelection event_selection_of(const nlohmann::json& query);

/// One event query object answered (docs/FORMAT.md §24.3); throws QueryError for a bad field
/// and std::invalid_argument from the cube (unknown category, zoom past the finest level);
/// QueryTooLarge for a series of more than `max_series_bins` bins (0: no limit).
nlohmann::json answer_event_json(const EventQueries& cube, std::string_view op,
                                 const nlohmann::json& query, std::size_t max_series_bins = 0);

/// Runs every query of `in` (one JSON object per line) and writes one answer per line to `out`,
/// for any op of is_json_op (query_json.cpp); returns the exit status (1 with one line on stderr
/// for a bad blob or query).
int run_json_query(const std::string& blob, const std::string& accel, const std::string& op,
                   const std::string& in, const std::string& out);

}  // namespace kiln::cli
