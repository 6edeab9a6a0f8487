// `kiln query --op count|series|tiles|topk` (issue 18): JSON lines in, JSON lines out, answered
// by the blob's EventQueries structure (the nanocube).
#pragma once

#include <string>

#include "kiln/runtime/capabilities.hpp"

namespace kiln::cli {

bool is_event_op(const std::string& op);

/// Runs every query of `in` (one JSON object per line) and writes one answer per line to `out`;
/// returns the exit status (1 with one line on stderr for a bad blob or query).
int run_event_query(const std::string& blob, const std::string& accel, const std::string& op,
                    const std::string& in, const std::string& out);

}  // namespace kiln::cli
