// What kiln_bench_nanocube's two files share: a query of the benchmark.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "kiln/runtime/nanocube.hpp"

namespace kiln::bench {

struct EventQuery {
  EventSelection s;
  std::uint32_t zoom = 0;  ///< tiles only
};

/// SQLite's p50/p99 on the same queries (nanocube_sqlite.cpp).
int sqlite_latency(const EventTableView& t, const EventGrid& g,
                   const std::vector<std::pair<std::string, std::vector<EventQuery>>>& sets);

}  // namespace kiln::bench
