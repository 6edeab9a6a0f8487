// Issue 21: `kiln serve`'s JSON API and tiles, over HTTP on localhost, against `kiln query`'s
// answers on the same blobs (a separate process: random boxes x time intervals x category
// filters for count, series, topk and tiles; point in polygon also against the CLI's CSV path),
// every error status with its message, the limits and gzip.
#include <gtest/gtest.h>
#include <httplib.h>

#include <chrono>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <thread>

#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_STATIC
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#include <stb/stb_image.h>
#pragma GCC diagnostic pop

#include "serve_server.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

using nlohmann::json;

constexpr double kLon0 = -120, kLon1 = -80, kLat0 = 30, kLat1 = 45;
const char* const kKinds[] = {"alpha", "beta", "gamma", "delta", "epsilon"};

// 3000 events over 30 days in a box of the US, two categories (a string column, a numeric one
// cut at edges), clustered on a few places so tiles and boxes see dense and empty cells.
std::string events_csv() {
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> u(0, 1);
  std::ostringstream csv;
  csv << "time,kind,size,lat,lon\n";
  for (int i = 0; i < 3000; ++i) {
    const int place = int(u(rng) * 6);
    const double lon = kLon0 + (place * 7 + u(rng) * (place == 5 ? 40 : 2)) * 0.95;
    const double lat = kLat0 + (place * 2 + u(rng) * (place == 5 ? 15 : 1)) * 0.9;
    const long t = 978307200 + long(u(rng) * 30 * 86400);
    csv << t << "," << kKinds[std::min(4, int(u(rng) * u(rng) * 6))] << "," << int(u(rng) * 100)
        << "," << lat << "," << lon << "\n";
  }
  return csv.str();
}

// A 4 x 3 grid of named squares over the same box.
std::string squares_geojson() {
  json features = json::array();
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 3; ++j) {
      const double x0 = kLon0 + i * 10, y0 = kLat0 + j * 5;
      features.push_back(
          {{"type", "Feature"},
           {"id", "sq" + std::to_string(i * 3 + j)},
           {"properties", {{"name", "Square " + std::to_string(i) + "-" + std::to_string(j)}}},
           {"geometry",
            {{"type", "Polygon"},
             {"coordinates",
              json::array({json::array({json::array({x0, y0}), json::array({x0 + 10, y0}),
                                        json::array({x0 + 10, y0 + 5}), json::array({x0, y0 + 5}),
                                        json::array({x0, y0})})})}}}});
    }
  return json{{"type", "FeatureCollection"}, {"features", features}}.dump();
}

// The two blobs, built once by `kiln build`.
class Blobs {
 public:
  static const Blobs& get() {
    static const Blobs blobs;
    return blobs;
  }
  std::string events, squares;

 private:
  Blobs() : events(dir_.file("events.kiln")), squares(dir_.file("squares.kiln")) {
    test::write_text(dir_.file("events.csv"), events_csv());
    test::write_text(dir_.file("squares.geojson"), squares_geojson());
    auto r = test::run_kiln("build " + test::quoted(dir_.file("events.csv")) + " -o " +
                            test::quoted(events) +
                            " --accel nanocube --lat lat --lon lon --time time --time-bin 1h "
                            "--category kind --category size=size:0,10,50,inf --max-level 12");
    EXPECT_EQ(r.exit_code, 0) << r.err;
    r = test::run_kiln("build " + test::quoted(dir_.file("squares.geojson")) + " -o " +
                       test::quoted(squares) + " --accel polygon-index");
    EXPECT_EQ(r.exit_code, 0) << r.err;
  }
  test::TempDir dir_;
};

// A server on a free loopback port, on its own thread, for one test.
class Running {
 public:
  explicit Running(std::vector<std::string> paths, serve::Limits limits = {})
      : catalog_(paths), server_(catalog_, {"127.0.0.1", 0, 2, limits}) {
    server_.bind();
    thread_ = std::thread([this] { server_.run(); });
    // httplib's stop() is a no-op before the accept loop runs: wait for it.
    httplib::Client probe("127.0.0.1", server_.port());
    for (int i = 0; i < 500 && !probe.Get("/api/blobs"); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ~Running() {
    server_.stop();
    thread_.join();
  }
  httplib::Client client() const { return httplib::Client("127.0.0.1", server_.port()); }
  // POST /api/query: (status, parsed body).
  std::pair<int, json> post(const std::string& body) const {
    auto c = client();
    const auto r = c.Post("/api/query", body, "application/json");
    if (!r) return {-1, json()};
    return {r->status, json::parse(r->body)};
  }

 private:
  serve::Catalog catalog_;
  serve::Server server_;
  std::thread thread_;
};

// `kiln query` on a .jsonl file of `queries`: its answers, one per line.
std::vector<json> cli_answers(const std::string& blob, const std::string& op,
                              const std::vector<json>& queries) {
  test::TempDir dir;
  std::string lines;
  for (const json& q : queries) lines += q.dump() + "\n";
  test::write_text(dir.file("q.jsonl"), lines);
  const auto r = test::run_kiln("query " + test::quoted(blob) + " --op " + op + " --in " +
                                test::quoted(dir.file("q.jsonl")) + " --out " +
                                test::quoted(dir.file("a.jsonl")));
  EXPECT_EQ(r.exit_code, 0) << r.err;
  std::vector<json> answers;
  std::istringstream in(test::read_text(dir.file("a.jsonl")));
  for (std::string line; std::getline(in, line);) answers.push_back(json::parse(line));
  return answers;
}

// Random selections: a box (or none), a time interval (or none), 0-2 category filters.
std::vector<json> random_selections(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<json> out;
  for (std::size_t i = 0; i < n; ++i) {
    json q = json::object();
    if (u(rng) < 0.7) {
      const double x = kLon0 + u(rng) * 40, y = kLat0 + u(rng) * 15;
      q["box"] = {x, y, x + u(rng) * 20, y + u(rng) * 8};
    }
    if (u(rng) < 0.7) {
      const long t0 = 978307200 + long(u(rng) * 25 * 86400);
      q["time"] = {t0, t0 + 3600 + long(u(rng) * 10 * 86400)};
    }
    if (u(rng) < 0.5) q["where"]["kind"] = {kKinds[int(u(rng) * 5)], kKinds[int(u(rng) * 5)]};
    if (u(rng) < 0.3) q["where"]["size"] = {u(rng) < 0.5 ? "0..10" : ">=50"};
    out.push_back(std::move(q));
  }
  return out;
}

TEST(Serve, EventAnswersEqualTheCli) {
  const Running server({Blobs::get().events, Blobs::get().squares});
  std::mt19937_64 rng(5);
  for (const std::string op : {"count", "series", "topk", "tiles"}) {
    std::vector<json> queries = random_selections(60, op.size() * 7);
    for (json& q : queries) {
      if (op == "series") q["bin"] = rng() % 2 ? "1d" : "6h";
      if (op == "topk") q["by"] = rng() % 2 ? "kind" : "size", q["k"] = 1 + rng() % 4;
      if (op == "tiles") q["zoom"] = 2 + rng() % 8;
    }
    const std::vector<json> expected = cli_answers(Blobs::get().events, op, queries);
    ASSERT_EQ(expected.size(), queries.size());
    // Half one query per request, half in batches of 10 (an array in, an array out).
    for (std::size_t i = 0; i < queries.size(); ++i) {
      json q = queries[i];
      q["op"] = op, q["blob"] = "events";
      if (i < 30) {
        const auto [status, answer] = server.post(q.dump());
        ASSERT_EQ(status, 200) << answer;
        EXPECT_EQ(answer, expected[i]) << op << " " << q;
        continue;
      }
      json batch = json::array();
      for (std::size_t k = i; k < i + 10; ++k) {
        json b = queries[k];
        b["op"] = op, b["blob"] = "events";
        batch.push_back(b);
      }
      const auto [status, answers] = server.post(batch.dump());
      ASSERT_EQ(status, 200) << answers;
      for (std::size_t k = 0; k < 10; ++k) EXPECT_EQ(answers[k], expected[i + k]) << op;
      i += 9;
    }
  }
}

TEST(Serve, PolygonAnswersEqualTheCli) {
  const Running server({Blobs::get().events, Blobs::get().squares});
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(0, 1);
  json points = json::array();
  std::string csv = "longitude,latitude\n";
  for (int i = 0; i < 500; ++i) {
    // Some on the squares' edges (the half-open rule decides), some outside.
    const double x = i % 5 ? kLon0 - 5 + u(rng) * 50 : kLon0 + 10 * int(u(rng) * 4);
    const double y = kLat0 - 2 + u(rng) * 19;
    points.push_back({x, y});
    csv += std::to_string(x) + "," + std::to_string(y) + "\n";
  }
  for (auto& p : points)  // the CSV holds the printed coordinates: query those
    p = {std::stod(std::to_string(p[0].get<double>())),
         std::stod(std::to_string(p[1].get<double>()))};
  const json q = {{"op", "polygon"}, {"blob", "squares"}, {"points", points}};
  const auto [status, answer] = server.post(q.dump());
  ASSERT_EQ(status, 200) << answer;
  const auto expected = cli_answers(Blobs::get().squares, "polygon", {{{"points", points}}});
  EXPECT_EQ(answer, expected.at(0));
  // The CLI's CSV path (its own code) names the same features.
  test::TempDir dir;
  test::write_text(dir.file("p.csv"), csv);
  const auto r =
      test::run_kiln("query " + test::quoted(Blobs::get().squares) + " --op polygon --in " +
                     test::quoted(dir.file("p.csv")) + " --out " + test::quoted(dir.file("a.csv")));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::istringstream rows(test::read_text(dir.file("a.csv")));
  std::string row;
  std::getline(rows, row);  // header
  std::size_t located = 0;
  for (std::size_t i = 0; std::getline(rows, row); ++i) {
    const json& f = answer["features"].at(i);
    const std::string index = row.substr(row.find(',', row.find(',') + 1) + 1);
    if (f.is_null()) {
      EXPECT_EQ(index, "-1,,") << i;
      continue;
    }
    ++located;
    EXPECT_EQ(index, std::to_string(f["index"].get<int>()) + "," + f["id"].get<std::string>() +
                         "," + f["name"].get<std::string>())
        << i;
  }
  EXPECT_GT(located, 200u);
  // Features meeting a box, and the click of the page: a point's feature by name.
  const auto [s2, box] =
      server.post(R"({"op": "polygons-in-box", "blob": "squares", "box": [-115, 34, -105, 38]})");
  ASSERT_EQ(s2, 200) << box;
  EXPECT_EQ(box["features"].size(), 4u);
  const auto [s3, one] =
      server.post(R"({"op": "polygon", "blob": "squares", "points": [[-95, 41]]})");
  EXPECT_EQ(one["features"][0]["name"], "Square 2-2");
  EXPECT_EQ(one["features"][0]["id"], "sq8");
}

// Decodes a PNG tile: (width, height, RGBA pixels).
std::vector<unsigned char> decode(const std::string& png, int& w, int& h) {
  int channels = 0;
  unsigned char* data = stbi_load_from_memory(reinterpret_cast<const unsigned char*>(png.data()),
                                              int(png.size()), &w, &h, &channels, 4);
  if (!data) return {};
  std::vector<unsigned char> pixels(data, data + std::size_t(w) * h * 4);
  stbi_image_free(data);
  return pixels;
}

TEST(Serve, HeatmapTilesShowTheCliTiles) {
  const Running server({Blobs::get().events, Blobs::get().squares});
  auto client = server.client();
  // Tile 3/1/3 and its cells at zoom 9 (4 x 4 pixels each) with a filter and an interval.
  const json q = {{"tile", {3, 1, 3}},
                  {"zoom", 9},
                  {"time", {978307200, 978307200 + 10 * 86400}},
                  {"where", {{"kind", {"alpha", "beta"}}}}};
  const auto cells = cli_answers(Blobs::get().events, "tiles", {q}).at(0)["tiles"];
  ASSERT_GT(cells.size(), 3u);
  const auto r =
      client.Get("/tiles/events/3/1/3.png?time=978307200,979171200&where=kind:alpha,beta");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(r->get_header_value("Content-Type"), "image/png");
  int w = 0, h = 0;
  const auto pixels = decode(r->body, w, h);
  ASSERT_EQ(w, 256);
  ASSERT_EQ(h, 256);
  std::size_t opaque = 0;
  for (std::size_t i = 3; i < pixels.size(); i += 4) opaque += pixels[i] == 255;
  EXPECT_EQ(opaque, cells.size() * 16);  // each non-empty cell a 4 x 4 block, nothing else
  for (const json& c : cells) {
    const std::size_t x = (c[1].get<std::size_t>() - 64) * 4,
                      y = (c[2].get<std::size_t>() - 192) * 4;
    EXPECT_EQ(pixels[(y * 256 + x) * 4 + 3], 255) << c;
  }
  // A polygon layer's tile: opaque, the squares' colours and the sea.
  const auto s = client.Get("/tiles/squares/3/1/3.png");
  ASSERT_TRUE(s);
  ASSERT_EQ(s->status, 200);
  EXPECT_EQ(decode(s->body, w, h).size(), 256u * 256 * 4);
}

TEST(Serve, BlobsDescribeEveryStructure) {
  const Running server({Blobs::get().events, Blobs::get().squares});
  auto client = server.client();
  const auto r = client.Get("/api/blobs");
  ASSERT_TRUE(r);
  const json blobs = json::parse(r->body)["blobs"];
  ASSERT_EQ(blobs.size(), 2u);
  EXPECT_EQ(blobs[0]["name"], "events");
  EXPECT_EQ(blobs[0]["structures"][0]["kind"], "nanocube");
  EXPECT_EQ(blobs[0]["events"]["rows"], 3000);
  EXPECT_EQ(blobs[0]["events"]["categories"][1]["labels"],
            json::array({"0..10", "10..50", ">=50"}));
  EXPECT_EQ(blobs[1]["structures"][0]["kind"], "polygon-index");
  EXPECT_TRUE(blobs[1]["structures"][0]["stats"].is_object());
  EXPECT_EQ(r->body.find(Blobs::get().events), std::string::npos);  // no server paths
  // The stats are those of `kiln dump --json`.
  for (std::size_t b = 0; b < 2; ++b) {
    const auto dump = test::run_kiln("dump --json " +
                                     test::quoted(b ? Blobs::get().squares : Blobs::get().events));
    ASSERT_EQ(dump.exit_code, 0) << dump.err;
    const json structure = json::parse(dump.out)["manifest"]["structures"][0];
    EXPECT_EQ(blobs[b]["structures"][0]["stats"], structure[structure["kind"].get<std::string>()]);
  }
}

TEST(Serve, ABatchStopsAtItsTimeLimit) {
  serve::Limits limits;
  limits.max_time = std::chrono::milliseconds(0);
  const Running server({Blobs::get().events}, limits);
  const auto [status, answer] = server.post(R"([{"op": "count"}, {"op": "count"}])");
  EXPECT_EQ(status, 503);
  EXPECT_NE(answer["error"].get<std::string>().find("ran past its 0 ms"), std::string::npos)
      << answer;
  EXPECT_EQ(server.post(R"({"op": "count"})").first, 200);  // one query is one step
}

// Every error: its status and a message naming what was wrong.
TEST(Serve, ErrorsSayWhatWasWrong) {
  serve::Limits limits;
  limits.max_request_bytes = 4096;
  limits.max_queries = 4;
  limits.max_answer_items = 50;
  const Running server({Blobs::get().events, Blobs::get().squares}, limits);
  const std::pair<std::string, std::pair<int, std::string>> cases[] = {
      {"{\"op\": \"count\"", {400, "malformed JSON"}},
      {R"({"op": "count", "blob": "events", "colour": 1})", {400, "unknown field 'colour'"}},
      {R"({"op": "count", "blob": "events", "box": [1, 2]})", {400, "'box' needs"}},
      {R"({"op": "count", "blob": "events", "time": ["yesterday", 5]})", {400, "'time' holds"}},
      {R"({"op": "tiles", "blob": "events", "zoom": 40})", {400, "zoom"}},
      {R"({"op": "topk", "blob": "events", "by": "colour"})", {400, "colour"}},
      {R"({"op": "count", "blob": "events", "where": {"kind": 3}})", {400, "'where': 'kind'"}},
      {R"({"op": "fly", "blob": "events"})", {400, "unknown op 'fly'"}},
      {R"({"blob": "events"})", {400, "'op' is needed"}},
      {R"({"op": "count"})", {400, "'blob' is needed: 2 blobs"}},
      {R"({"op": "count", "blob": "nope"})", {404, "no blob named 'nope'"}},
      {R"({"op": "count", "blob": "events", "structure": "kd"})", {404, "no structure 'kd'"}},
      {R"({"op": "count", "blob": "squares"})", {404, "no structure that can answer aggregate"}},
      {R"({"op": "polygon", "blob": "squares", "points": [[1]]})", {400, "'points' needs"}},
      {R"([1, 2, 3, 4, 5])", {413, "5 queries in one request, more than 4"}},
      {R"({"op": "series", "blob": "events", "bin": "1h"})", {413, "more than 50"}},
      {R"({"op": "series", "blob": "events", "bin": 3600, "time": [0, 4000000000]})",
       {413, "the series would hold 1111112 bins, more than 50"}},
      {R"({"op": "tiles", "blob": "events", "zoom": 12})", {413, "tiles, more than 50"}},
      {"[" + std::string(5000, ' ') + "]", {413, ""}},
      {R"([{"op": "count", "blob": "events"}, {"op": "count", "blob": "x"}])",
       {404, "query 1: no blob named 'x'"}}};
  for (const auto& [body, expected] : cases) {
    const auto [status, answer] = server.post(body);
    EXPECT_EQ(status, expected.first) << body.substr(0, 80) << " -> " << answer;
    ASSERT_TRUE(answer.contains("error")) << answer;
    EXPECT_NE(answer["error"].get<std::string>().find(expected.second), std::string::npos)
        << answer;
  }
  auto client = server.client();
  for (const auto& [path, status] :
       std::vector<std::pair<std::string, int>>{{"/nothing", 404},
                                                {"/tiles/nope/1/0/0.png", 404},
                                                {"/tiles/events/2/9/0.png", 404},
                                                {"/tiles/events/99/0/0.png", 404},
                                                {"/tiles/events/1/0/0.png?colour=red", 400},
                                                {"/tiles/events/1/0/0.png?where=kind", 400},
                                                {"/tiles/events/1/0/0.png?where=shape:round", 400},
                                                {"/../../etc/passwd", 404},
                                                {"/leaflet/../../../etc/passwd", 404}}) {
    const auto r = client.Get(path);
    ASSERT_TRUE(r) << path;
    EXPECT_EQ(r->status, status) << path;
    EXPECT_TRUE(json::parse(r->body).contains("error")) << path << " " << r->body;
  }
}

TEST(Serve, CompressesWhenTheClientAccepts) {
  const Running server({Blobs::get().events});
  auto client = server.client();
  client.set_decompress(false);
  const auto r = client.Post("/api/query", {{"Accept-Encoding", "gzip"}},
                             R"({"op": "series", "bin": "1h"})", "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_EQ(r->get_header_value("Content-Encoding"), "gzip");
  // One blob served: "blob" may be left out; the page is served too.
  const auto plain = server.post(R"({"op": "count"})");
  EXPECT_EQ(plain.second["count"], 3000);
  const auto page = server.client().Get("/");
  ASSERT_TRUE(page);
  EXPECT_NE(page->body.find("data-testid=\"total-count\""), std::string::npos);
}

}  // namespace
}  // namespace kiln
