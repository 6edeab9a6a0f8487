// One JSON query object in, one JSON answer out: the per-op answering behind `kiln query`'s JSON
// lines and `kiln serve`'s POST /api/query (one code path, so both give identical answers).
#pragma once

#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <string_view>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/capabilities.hpp"

namespace kiln {

/// A query that cannot be answered as written: a malformed or unknown field, a bad value. The
/// message names the field.
class QueryError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// A query whose answer would be larger than the caller allows (checked before the work).
class QueryTooLarge : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The ops answered from JSON: count, series, tiles, topk (events); polygon, polygons-in-box
/// (polygon layers); range, knn2d, radius2d (2D point tables).
bool is_json_op(std::string_view op);

/// Whether `view` has the capability `op` needs.
bool view_answers(const StructureView& view, std::string_view op);

/// What `op` needs, for messages ("answer aggregate event queries").
std::string_view op_ability(std::string_view op);

/// Answers one query object (the fields of one `kiln query` JSON line, docs/FORMAT.md §22, §24.3
/// and docs/SERVE.md) with `view`, a structure of `blob` that answers `op`. Fields other than
/// the op's (and "op", "blob", "structure", which the caller reads) are refused. Throws
/// QueryError (a bad query) or std::invalid_argument (from the structure: an unknown category,
/// a zoom past the finest level). With `max_series_bins` > 0, a series that would hold more bins
/// throws QueryTooLarge before it is counted.
nlohmann::json answer_json_query(const Blob& blob, const StructureView& view, std::string_view op,
                                 const nlohmann::json& query, std::size_t max_series_bins = 0);

/// Most points of one polygon query and largest k of one knn2d query (a request's work stays
/// bounded).
inline constexpr std::size_t kMaxQueryPoints = 10000;
inline constexpr std::size_t kMaxQueryK = 10000;

}  // namespace kiln
