// Nanocube query latency (issue 18): p50/p99 per query type on one thread, against the
// brute-force scan of the mapped table and (with --sqlite) SQLite over an indexed table of the
// same columns. Usage: kiln_bench_nanocube BLOB [--queries N] [--scan-queries M] [--sqlite].
// Build the blob first with `kiln build ... --accel nanocube` (docs/BENCHMARKS.md, "Nanocube").
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/nanocube.hpp"
#include "nanocube_bench.hpp"

namespace {

using namespace kiln;
using Clock = std::chrono::steady_clock;

using Query = bench::EventQuery;

// Queries of one type: a random box around an event (0.5 to 30 degrees), a random month-or-less
// (topk-all: all time; topk-month, topk-week: exactly 30 or 7 days), a filter on the first
// category half of the time (not for top-k); tiles: a 256 x 256-tile view.
std::vector<Query> make_queries(const std::string& type, const EventTableView& t, std::uint32_t L,
                                std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Query> out;
  for (std::size_t i = 0; i < n; ++i) {
    Query q;
    const auto& p = t.points[std::size_t(u(rng) * double(t.rows())) % t.rows()];
    if (type == "tiles") {
      const std::uint32_t z = std::min<std::uint32_t>(L - std::min(L, 8u), 1 + rng() % 4);
      q.s.tile = std::array<std::uint32_t, 3>{z, format::mercator_cell_x(p.x, z),
                                              format::mercator_cell_y(p.y, z)};
      q.zoom = std::min(L, z + 8);
    } else {
      const double w = 0.5 * std::pow(60.0, u(rng));
      q.s.box = format::Box2d{{p.x - w, p.y - w / 2}, {p.x + w, p.y + w / 2}};
    }
    const double span = double(t.time_max - t.time_min);
    const auto t0 = t.time_min + std::int64_t(u(rng) * span * 0.8);
    auto t1 = t0 + std::int64_t(u(rng) * 31 * 86400);
    if (type == "topk-month") t1 = t0 + 30 * 86400;
    if (type == "topk-week") t1 = t0 + 7 * 86400;
    if (type != "topk-all") q.s.time = std::array<std::int64_t, 2>{t0, t1};
    if (!t.categories.empty() && u(rng) < 0.5 && !type.starts_with("topk"))
      q.s.where = {{t.categories[0].name,
                    {std::string(t.label(0, std::uint32_t(rng() % t.categories[0].label_count)))}}};
    out.push_back(q);
  }
  return out;
}

// Runs each query once, returns (p50, p99) in milliseconds and a checksum of the answers.
std::pair<double, double> latency(const std::vector<Query>& qs,
                                  const std::function<std::uint64_t(const Query&)>& run,
                                  std::uint64_t& checksum) {
  std::vector<double> ms;
  for (const Query& q : qs) {
    const auto start = Clock::now();
    checksum += run(q);
    ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - start).count());
  }
  std::sort(ms.begin(), ms.end());
  return {ms[ms.size() / 2], ms[std::min(ms.size() - 1, ms.size() * 99 / 100)]};
}

std::function<std::uint64_t(const Query&)> runner(const EventQueries& e, const std::string& type,
                                                  const std::string& by) {
  if (type == "count") return [&e](const Query& q) { return e.count(q.s); };
  if (type == "series")
    return [&e](const Query& q) { return std::uint64_t(e.series(q.s, 86400).size()); };
  if (type == "tiles")
    return [&e](const Query& q) { return std::uint64_t(e.tiles(q.s, q.zoom).size()); };
  return [&e, by](const Query& q) {
    const auto top = e.topk(q.s, by, 10);
    return top.empty() ? 0 : top.front().count;
  };
}

// Top-k's work where the view reports it (a view with topk_traced; an older build prints
// nothing): the share of queries the threshold walk answered and the labels it counted exactly.
template <class View>
std::string topk_work(const View& cube, const std::vector<Query>& qs, const std::string& by) {
  if constexpr (requires { typename View::TopkTrace; }) {
    std::vector<std::size_t> counted, nodes, lists;
    std::size_t walked = 0, blocks = 0;
    for (const Query& q : qs) {
      typename View::TopkTrace trace;
      cube.topk_traced(q.s, by, 10, trace);
      walked += trace.path == View::TopkTrace::Path::kThreshold;
      blocks += trace.block_lists > 0;
      counted.push_back(trace.labels_counted);
      nodes.push_back(trace.counted_labels);
      lists.push_back(trace.block_lists);
    }
    std::sort(counted.begin(), counted.end());
    std::sort(nodes.begin(), nodes.end());
    std::sort(lists.begin(), lists.end());
    return "  walk " + std::to_string(100 * walked / qs.size()) + "% (blocks " +
           std::to_string(100 * blocks / qs.size()) + "%), labels counted p50 " +
           std::to_string(counted[counted.size() / 2]) + " counted-node labels p50 " +
           std::to_string(nodes[nodes.size() / 2]) + " p90 " +
           std::to_string(nodes[nodes.size() * 9 / 10]) + " lists p50 " +
           std::to_string(lists[lists.size() / 2]);
  } else {
    return "";
  }
}

}  // namespace

int main(int argc, char** argv) {
  const bool help = argc >= 2 && (!std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h"));
  if (argc < 2 || help) {
    std::fprintf(
        help ? stdout : stderr,
        "usage: %s BLOB [--queries N] [--scan-queries M] [--sqlite] [--only TYPE]\n"
        "Latency p50/p99 of count, series, tiles and topk on the blob's nanocube against a\n"
        "scan of its mapped table (and SQLite with --sqlite), 1 thread.\n",
        argv[0]);
    return help ? 0 : 2;
  }
  std::size_t queries = 1000, scan_queries = 20;
  bool sqlite = false;
  std::string only;  // one query type, else all
  for (int i = 2; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--queries") && i + 1 < argc)
      queries = std::stoul(argv[++i]);
    else if (!std::strcmp(argv[i], "--scan-queries") && i + 1 < argc)
      scan_queries = std::stoul(argv[++i]);
    else if (!std::strcmp(argv[i], "--sqlite"))
      sqlite = true;
    else if (!std::strcmp(argv[i], "--only") && i + 1 < argc)
      only = argv[++i];
  }
  const Blob blob = Blob::open_file(argv[1]);
  const NanocubeView cube = NanocubeView::from_blob(blob, *blob.structure("nanocube"));
  const EventScan scan(blob.event_table(), cube.grid());
  const EventTableView& t = cube.table();
  const std::string by = t.categories.empty() ? "" : t.categories[0].name;
  std::printf("%zu events, max level %u, %zu queries per type (scan: %zu), 1 thread\n", t.rows(),
              cube.grid().max_level, queries, scan_queries);
  std::printf("%-10s %12s %12s %12s %12s\n", "query", "cube p50 ms", "cube p99 ms", "scan p50 ms",
              "scan p99 ms");
  std::vector<std::pair<std::string, std::vector<Query>>> sets;
  // topk-all: the same boxes over all time, which the stored rankings answer alone.
  for (const std::string type :
       {"count", "series", "tiles", "topk", "topk-all", "topk-month", "topk-week"}) {
    if ((type.starts_with("topk") && by.empty()) || (!only.empty() && type != only)) continue;
    const auto qs = make_queries(type, t, cube.grid().max_level, queries, 42);
    std::uint64_t a = 0, b = 0, c = 0;
    const auto [p50, p99] = latency(qs, runner(cube, type, by), a);
    const std::vector<Query> few(qs.begin(), qs.begin() + std::min(scan_queries, qs.size()));
    const auto [s50, s99] = latency(few, runner(scan, type, by), b);
    latency(few, runner(cube, type, by), c);
    std::printf("%-10s %12.4f %12.4f %12.2f %12.2f%s%s\n", type.c_str(), p50, p99, s50, s99,
                b == c ? "" : "  ANSWERS DIFFER",
                type.starts_with("topk") ? topk_work(cube, qs, by).c_str() : "");
    sets.emplace_back(type, few);
  }
  return sqlite ? kiln::bench::sqlite_latency(t, cube.grid(), sets) : 0;
}
