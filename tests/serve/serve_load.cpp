// kiln_serve_load: a bounded load on a running `kiln serve` (tests/serve/serve_load_test.py and
// docs/BENCHMARKS.md): `requests` requests over `connections` keep-alive connections, a mix of
// count, topk, series and heatmap tiles on one event blob with random selections; prints one
// JSON line: totals, errors by kind and the client-side latency p50/p99 per request kind.
#include <httplib.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <thread>
#include <vector>

namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

struct Args {
  int port = 8080;
  std::string blob, by;
  std::int64_t t0 = 0, t1 = 0;
  std::size_t requests = 20000, connections = 32;
  std::string kinds = "count,topk,series,tile";
};

struct Result {
  std::map<std::string, std::vector<double>> ms;  // per kind
  std::map<std::string, std::size_t> errors;      // "status 400", "transport Read", ...
  std::size_t ok = 0;
};

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::size_t start = 0;
  for (std::size_t comma; (comma = s.find(',', start)) != std::string::npos; start = comma + 1)
    out.push_back(s.substr(start, comma - start));
  out.push_back(s.substr(start));
  return out;
}

// One request of `kind` with a random time interval (and tile address); true when answered 200
// with a body that parses (JSON) or starts as a PNG.
bool one(httplib::Client& client, const Args& a, const std::string& kind, std::mt19937_64& rng,
         Result& r) {
  const std::int64_t span = std::max<std::int64_t>(3600, a.t1 - a.t0);
  const std::int64_t from = a.t0 + std::int64_t(rng() % std::uint64_t(span));
  const std::int64_t to = from + 3600 + std::int64_t(rng() % std::uint64_t(span / 4 + 1));
  auto request = [&]() -> httplib::Result {
    if (kind == "tile") {
      const unsigned z = 3 + rng() % 4, n = 1u << z;
      // Tiles over the continental US (x 0.17-0.33, y 0.35-0.45 of the world at any zoom).
      const unsigned x = unsigned(n * (0.17 + 0.16 * double(rng() % 1000) / 1000));
      const unsigned y = unsigned(n * (0.35 + 0.10 * double(rng() % 1000) / 1000));
      return client.Get("/tiles/" + a.blob + "/" + std::to_string(z) + "/" + std::to_string(x) +
                        "/" + std::to_string(y) + ".png?time=" + std::to_string(from) + "," +
                        std::to_string(to));
    }
    {
      json q = {{"op", kind}, {"blob", a.blob}, {"time", {from, to}}};
      if (kind == "topk") q["by"] = a.by, q["k"] = 10;
      if (kind == "series") q["bin"] = "1d", q["time"] = {a.t0, a.t1};
      return client.Post("/api/query", q.dump(), "application/json");
    }
    return client.Get("/tiles/" + a.blob + "/0/0/0.png");  // unreachable
  };
  const httplib::Result res = request();
  if (!res) {
    ++r.errors["transport " + httplib::to_string(res.error())];
    return false;
  }
  if (res->status != 200) {
    ++r.errors["status " + std::to_string(res->status)];
    return false;
  }
  const bool complete =
      kind == "tile" ? res->body.compare(1, 3, "PNG") == 0 : json::accept(res->body);
  if (!complete) ++r.errors["incomplete body"];
  return complete;
}

void worker(const Args& a, std::size_t id, std::atomic<std::size_t>& next, Result& r) {
  httplib::Client client("127.0.0.1", a.port);
  client.set_keep_alive(true);
  client.set_tcp_nodelay(true);
  client.set_read_timeout(10, 0);
  std::mt19937_64 rng(id * 7919 + 1);
  const std::vector<std::string> kinds = split(a.kinds);
  for (std::size_t i; (i = next.fetch_add(1)) < a.requests;) {
    const std::string& kind = kinds[i % kinds.size()];
    const auto start = Clock::now();
    if (one(client, a, kind, rng, r)) {
      r.ms[kind].push_back(std::chrono::duration<double, std::milli>(Clock::now() - start).count());
      ++r.ok;
    }
  }
}

double percentile(std::vector<double>& v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, std::size_t(p * double(v.size())))];
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i], value = argv[i + 1];
    if (key == "--port")
      a.port = std::stoi(value);
    else if (key == "--blob")
      a.blob = value;
    else if (key == "--by")
      a.by = value;
    else if (key == "--time")
      a.t0 = std::stoll(split(value)[0]), a.t1 = std::stoll(split(value)[1]);
    else if (key == "--requests")
      a.requests = std::stoul(value);
    else if (key == "--connections")
      a.connections = std::stoul(value);
    else if (key == "--kinds")
      a.kinds = value;
    else {
      std::cerr << "kiln_serve_load: unknown option " << key << "\n";
      return 2;
    }
  }
  if (a.blob.empty() || a.by.empty() || a.t1 <= a.t0) {
    std::cerr << "usage: kiln_serve_load --port P --blob NAME --by CATEGORY --time T0,T1 "
                 "[--requests N] [--connections C] [--kinds count,topk,series,tile]\n";
    return 2;
  }
  std::vector<Result> results(a.connections);
  std::atomic<std::size_t> next{0};
  const auto start = Clock::now();
  std::vector<std::thread> threads;
  for (std::size_t c = 0; c < a.connections; ++c)
    threads.emplace_back(worker, std::cref(a), c, std::ref(next), std::ref(results[c]));
  for (auto& t : threads) t.join();
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  Result all;
  for (auto& r : results) {
    all.ok += r.ok;
    for (auto& [k, v] : r.ms) all.ms[k].insert(all.ms[k].end(), v.begin(), v.end());
    for (auto& [k, n] : r.errors) all.errors[k] += n;
  }
  json out = {{"requests", a.requests}, {"connections", a.connections}, {"ok", all.ok},
              {"seconds", seconds},     {"errors", all.errors},         {"kinds", json::object()}};
  std::vector<double> every;
  for (auto& [k, v] : all.ms) {
    every.insert(every.end(), v.begin(), v.end());
    out["kinds"][k] = {
        {"n", v.size()}, {"p50_ms", percentile(v, 0.5)}, {"p99_ms", percentile(v, 0.99)}};
  }
  out["p50_ms"] = percentile(every, 0.5);
  out["p99_ms"] = percentile(every, 0.99);
  std::cout << out.dump() << std::endl;
  return 0;
}
