// The SQLite side of kiln_bench_nanocube: the table as (cx, cy, bin, c0) rows with indexes on
// (c0, bin) and (cx, cy), and the same queries as SQL; counts are checked against the cube.
#include <sqlite3.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "nanocube_bench.hpp"

namespace kiln::bench {

int sqlite_latency(const EventTableView& t, const EventGrid& g,
                   const std::vector<std::pair<std::string, std::vector<EventQuery>>>& sets) {
  using Query = EventQuery;
  sqlite3* db = nullptr;
  sqlite3_open(":memory:", &db);
  sqlite3_exec(db, "CREATE TABLE ev(cx INT, cy INT, bin INT, c0 INT);", nullptr, nullptr, nullptr);
  sqlite3_exec(db, "BEGIN", nullptr, nullptr, nullptr);
  sqlite3_stmt* insert = nullptr;
  sqlite3_prepare_v2(db, "INSERT INTO ev VALUES(?,?,?,?)", -1, &insert, nullptr);
  const auto load = std::chrono::steady_clock::now();
  for (std::size_t i = 0; i < t.rows(); ++i) {
    sqlite3_bind_int64(insert, 1, kiln::format::mercator_cell_x(t.points[i].x, g.max_level));
    sqlite3_bind_int64(insert, 2, kiln::format::mercator_cell_y(t.points[i].y, g.max_level));
    sqlite3_bind_int64(insert, 3, (t.times[i] - g.time_origin) / g.time_bin);
    sqlite3_bind_int64(insert, 4, t.categories.empty() ? 0 : t.codes[i]);
    sqlite3_step(insert);
    sqlite3_reset(insert);
  }
  sqlite3_finalize(insert);
  sqlite3_exec(db, "COMMIT; CREATE INDEX ev_c0 ON ev(c0, bin); CREATE INDEX ev_xy ON ev(cx, cy);",
               nullptr, nullptr, nullptr);
  std::printf("sqlite: loaded and indexed in %.1f s\n",
              std::chrono::duration<double>(std::chrono::steady_clock::now() - load).count());
  std::printf("%-7s %14s %14s\n", "query", "sqlite p50 ms", "sqlite p99 ms");
  for (const auto& [type, queries] : sets) {
    std::vector<double> ms;
    for (const Query& q : queries) {
      const kiln::ResolvedSelection r = kiln::resolve_event_selection(q.s, t, g);
      const std::uint32_t shift = g.max_level - q.zoom;
      std::string where = "cx BETWEEN " + std::to_string(r.x0) + " AND " + std::to_string(r.x1) +
                          " AND cy BETWEEN " + std::to_string(r.y0) + " AND " +
                          std::to_string(r.y1) + " AND bin >= " + std::to_string(r.b0) +
                          " AND bin < " + std::to_string(r.b1);
      if (!r.allowed.empty() && !r.allowed[0].empty()) {
        std::string in;
        for (std::size_t c = 0; c < r.allowed[0].size(); ++c)
          if (r.allowed[0][c]) in += (in.empty() ? "" : ",") + std::to_string(c);
        where += " AND c0 IN (" + in + ")";
      }
      const std::string sql =
          type == "count"    ? "SELECT count(*) FROM ev WHERE " + where
          : type == "series" ? "SELECT bin / 24, count(*) FROM ev WHERE " + where + " GROUP BY 1"
          : type == "tiles"
              ? "SELECT cx >> " + std::to_string(shift) + ", cy >> " + std::to_string(shift) +
                    ", count(*) FROM ev WHERE " + where + " GROUP BY 1, 2"
              : "SELECT c0, count(*) AS n FROM ev WHERE " + where +
                    " GROUP BY c0 ORDER BY n DESC, c0 LIMIT 10";
      const auto start = std::chrono::steady_clock::now();
      sqlite3_stmt* st = nullptr;
      sqlite3_prepare_v2(db, sql.c_str(), -1, &st, nullptr);
      while (sqlite3_step(st) == SQLITE_ROW) {
      }
      sqlite3_finalize(st);
      ms.push_back(
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
              .count());
    }
    std::sort(ms.begin(), ms.end());
    std::printf("%-7s %14.2f %14.2f\n", type.c_str(), ms[ms.size() / 2],
                ms[std::min(ms.size() - 1, ms.size() * 99 / 100)]);
  }
  sqlite3_close(db);
  return 0;
}

}  // namespace kiln::bench
