// Issue 18: event tables and the nanocube. Every answer is checked against EventScan, a
// brute-force scan of the blob's mapped table, on a generated table and on the first 100,000
// flights; sharing on and off, round trips, thread counts, forged bytes and bad input.
#include <gtest/gtest.h>
#include <zstd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/event_table.hpp"
#include "kiln/compiler/import_events.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/nanocube.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

const std::string kEvents = KILN_MESH_DIR "/../events";
const std::string kFlights = kEvents + "/flights-3m.csv.zst";

// Clustered points (half of them exactly on a cluster's centre, as flights sit on airports),
// times over 60 days, a Zipf-like string category and a numeric one cut at edges.
EventTable generated_table(std::size_t rows, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> spread(0, 1);
  std::vector<format::Double2> centres;
  for (int i = 0; i < 16; ++i) centres.push_back({-130 + 70 * u(rng), 25 + 25 * u(rng)});
  EventTable t;
  t.categories = {{"kind", "kind", {}, {}},
                  {"delay", "delay_min", {-INFINITY, 0, 15, 60, INFINITY}, {}}};
  for (int i = 0; i < 40; ++i) t.categories[0].labels.push_back("L" + std::to_string(10 + i));
  t.categories[1].labels = edge_labels(t.categories[1].edges);
  std::vector<std::uint32_t> kinds, delays;
  for (std::size_t r = 0; r < rows; ++r) {
    format::Double2 p = centres[std::size_t(u(rng) * 16) % 16];
    if (u(rng) < 0.5) p = {p.x + 2 * spread(rng), p.y + 1.5 * spread(rng)};
    t.points.push_back(p);
    t.times.push_back(978307200 + std::int64_t(u(rng) * 60 * 86400));
    kinds.push_back(std::uint32_t(40 * std::pow(u(rng), 3)));
    const double delay = 10 + 30 * spread(rng);
    delays.push_back(delay < 0 ? 0 : delay < 15 ? 1 : delay < 60 ? 2 : 3);
  }
  t.codes = kinds;
  t.codes.insert(t.codes.end(), delays.begin(), delays.end());
  index_event_labels(t);
  return t;
}

std::vector<std::byte> cube_blob(const EventTable& table, const std::string& options,
                                 unsigned threads = 2, bool compress = false) {
  Scene scene;
  scene.events = table;
  return test::blob_with(scene, "nanocube:" + options, threads, compress);
}

// An opened blob with its cube and the reference scan.
struct Opened {
  AlignedBuffer bytes;
  Blob blob;
  std::unique_ptr<StructureView> view;
  std::unique_ptr<EventScan> scan;
  explicit Opened(std::span<const std::byte> b)
      : bytes(test::aligned_copy(b)), blob(Blob::open_memory(bytes.bytes(), "cube")) {
    view = open_structure(blob, "nanocube");
    const NanocubeView cube = NanocubeView::from_blob(blob, *blob.structure("nanocube"));
    scan = std::make_unique<EventScan>(blob.event_table(), cube.grid());
  }
  const EventQueries& cube() const { return *view->events(); }
};

EventSelection random_selection(std::mt19937_64& rng, const EventTableView& t,
                                std::uint32_t level) {
  std::uniform_real_distribution<double> u(0, 1);
  EventSelection s;
  const auto& p = t.points[std::size_t(u(rng) * double(t.rows())) % t.rows()];
  const int space = int(u(rng) * 4);
  if (space & 1) {
    const double w = std::pow(10.0, -2 + 3.5 * u(rng)), h = std::pow(10.0, -2 + 3.5 * u(rng));
    s.box =
        format::Box2d{{p.x - w * u(rng), p.y - h * u(rng)}, {p.x + w * u(rng), p.y + h * u(rng)}};
  }
  if (space & 2) {
    const auto z = std::uint32_t(u(rng) * (level + 1)) % (level + 1);
    s.tile = std::array<std::uint32_t, 3>{z, format::mercator_cell_x(p.x, z),
                                          format::mercator_cell_y(p.y, z)};
  }
  if (u(rng) < 0.6) {
    const double span = double(t.time_max - t.time_min);
    const auto t0 = t.time_min - 3600 + std::int64_t(u(rng) * span);
    s.time = std::array<std::int64_t, 2>{t0, t0 + std::int64_t(u(rng) * span * 0.5)};
  }
  for (std::size_t c = 0; c < t.categories.size(); ++c) {
    if (u(rng) < 0.6) continue;
    std::vector<std::string> labels;
    for (int i = 0, n = 1 + int(u(rng) * 3); i < n; ++i)
      labels.emplace_back(t.label(c, std::uint32_t(u(rng) * double(t.categories[c].label_count)) %
                                         std::uint32_t(t.categories[c].label_count)));
    if (u(rng) < 0.1) labels.push_back("no such label");
    s.where.emplace_back(t.categories[c].name, labels);
  }
  return s;
}

bool same_tiles(const std::vector<EventTileCount>& a, const std::vector<EventTileCount>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (a[i].z != b[i].z || a[i].x != b[i].x || a[i].y != b[i].y || a[i].count != b[i].count)
      return false;
  return true;
}

bool same_topk(const std::vector<EventLabelCount>& a, const std::vector<EventLabelCount>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (a[i].label != b[i].label || a[i].count != b[i].count) return false;
  return true;
}

// Query i asks op i % 4 (count, series, tiles, topk); counts are asked every time. Returns the
// number of non-empty answers (so a test can see its queries select something).
std::size_t expect_agreement(const EventQueries& cube, const EventQueries& reference,
                             const EventTableView& table, const EventGrid& grid,
                             std::size_t queries, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::size_t non_empty = 0;
  for (std::size_t i = 0; i < queries; ++i) {
    const EventSelection s = random_selection(rng, table, grid.max_level);
    const std::uint64_t n = reference.count(s);
    non_empty += n != 0;
    EXPECT_EQ(cube.count(s), n) << "query " << i;
    const EventSnap a = cube.snap(s), b = reference.snap(s);
    EXPECT_TRUE(a.t0 == b.t0 && a.t1 == b.t1 && a.box.min.x == b.box.min.x &&
                a.box.max.y == b.box.max.y);
    if (i % 4 == 1) {
      const std::int64_t width = grid.time_bin * (rng() % 2 ? 1 : 24);
      EXPECT_EQ(cube.series(s, width), reference.series(s, width)) << "query " << i;
    } else if (i % 4 == 2) {
      const auto zoom = std::uint32_t(rng() % (grid.max_level + 1));
      EXPECT_TRUE(same_tiles(cube.tiles(s, zoom), reference.tiles(s, zoom))) << "query " << i;
    } else if (i % 4 == 3) {
      const std::string& by = table.categories[rng() % table.categories.size()].name;
      const std::size_t k = 1 + rng() % 8;
      EXPECT_TRUE(same_topk(cube.topk(s, by, k), reference.topk(s, by, k))) << "query " << i;
    }
    if (::testing::Test::HasFailure()) break;  // one failing query is enough to read
  }
  return non_empty;
}

TEST(Nanocube, GeneratedTableAgreesWithBruteForce) {
  const EventTable table = generated_table(6000, 1);
  const Opened o(cube_blob(table, "max-level=14,time-bin=1h"));
  const auto& cube = static_cast<const NanocubeView&>(o.cube());
  EXPECT_EQ(cube.count({}), table.rows());
  const std::size_t non_empty =
      expect_agreement(cube, *o.scan, o.blob.event_table(), cube.grid(), 1200, 7);
  EXPECT_GT(non_empty, 600u);
}

// Topkube's rankings: the root's equals per-label counts over the whole table, verify's deep
// check holds, and a top-k over everything counts only a few of the 40 Zipf-like labels exactly
// (the rest are ruled out by the rankings' bound) yet equals the scan.
TEST(Nanocube, TopkubeRankingsPruneAndAgreeWithTheScan) {
  const EventTable table = generated_table(6000, 9);
  const Opened o(cube_blob(table, "max-level=10,time-bin=1d"));
  const auto& cube = static_cast<const NanocubeView&>(o.cube());
  EXPECT_TRUE(cube.rankings_consistent());
  const std::uint32_t root = static_cast<std::uint32_t>(cube.dimension_nodes()[1] - 1);
  std::vector<std::uint64_t> counts(table.categories[0].labels.size(), 0);
  for (std::size_t r = 0; r < table.rows(); ++r) ++counts[table.codes[r]];
  const auto ranked = cube.ranking(0, root);
  std::uint64_t total = 0;
  for (std::size_t i = 0; i < ranked.size(); ++i) {
    EXPECT_EQ(ranked[i].count, counts[ranked[i].label]);
    if (i > 0) {
      EXPECT_GE(ranked[i - 1].count, ranked[i].count);
    }
    total += ranked[i].count;
  }
  EXPECT_EQ(total, table.rows());
  // All time, no other filter: the rankings alone answer.
  std::size_t counted = 1;
  EXPECT_TRUE(same_topk(cube.topk_counting({}, "kind", 3, counted), o.scan->topk({}, "kind", 3)));
  EXPECT_EQ(counted, 0u);
  // Most of the time range: the threshold algorithm counts a few labels, rules out the rest.
  EventSelection most;
  most.time = std::array<std::int64_t, 2>{978307200, 978307200 + 50 * 86400};
  const auto top = cube.topk_counting(most, "kind", 3, counted);
  EXPECT_TRUE(same_topk(top, o.scan->topk(most, "kind", 3)));
  EXPECT_GE(counted, 3u);
  EXPECT_LT(counted, 20u) << "the rankings should rule out most of the 40 labels";
}

TEST(Nanocube, SharingOffGivesTheSameAnswersAndMoreBytes) {
  const EventTable table = generated_table(3000, 2);
  const auto shared = cube_blob(table, "max-level=10,time-bin=1d");
  const auto copied = cube_blob(table, "max-level=10,time-bin=1d,sharing=off");
  EXPECT_LT(shared.size(), copied.size());
  const Opened a(shared), b(copied);
  const auto& cube = static_cast<const NanocubeView&>(a.cube());
  expect_agreement(a.cube(), b.cube(), a.blob.event_table(), cube.grid(), 400, 3);
  expect_agreement(b.cube(), *b.scan, b.blob.event_table(), cube.grid(), 200, 4);
}

TEST(Nanocube, ByteIdenticalForAnyThreadCountAndRoundTrips) {
  const EventTable table = generated_table(2000, 3);
  const auto one = cube_blob(table, "max-level=12", 1);
  EXPECT_EQ(one, cube_blob(table, "max-level=12", 2));
  EXPECT_EQ(one, cube_blob(table, "max-level=12", 8));
  test::TempDir dir;
  const std::string path = dir.path().string() + "/events.kiln";
  test::write_file(path, one);
  const Blob file = Blob::open_file(path);
  file.verify();
  const Opened memory(one), zstd(cube_blob(table, "max-level=12", 2, true));
  const auto from_file = open_structure(file, "nanocube");
  const auto& grid = static_cast<const NanocubeView&>(memory.cube()).grid();
  expect_agreement(*from_file->events(), memory.cube(), memory.blob.event_table(), grid, 100, 5);
  expect_agreement(zstd.cube(), memory.cube(), memory.blob.event_table(), grid, 100, 6);
  EXPECT_EQ(test::open_and_verify(one), "");
}

// Any byte of any section changed (checksums recomputed so the structural checks must catch
// it): open refuses it, or every query stays in range (ASan runs this too).
TEST(Nanocube, ForgedBytesAreRefusedOrSafe) {
  const EventTable table = generated_table(400, 4);
  const auto blob = cube_blob(table, "max-level=8,time-bin=1d");
  const Blob clean = Blob::open_memory(test::aligned_copy(blob).bytes());
  std::mt19937_64 rng(9);
  std::size_t refused = 0, tried = 0;
  for (std::uint32_t s = 1; s < clean.sections().size(); ++s) {
    const std::uint64_t size = clean.sections()[s].raw_size;
    for (int k = 0; k < 24 && size > 0; ++k, ++tried) {
      const std::size_t offset = rng() % size;
      const std::byte value{std::uint8_t(rng() % 256)};
      const AlignedBuffer forged = test::forged_copy(blob, s, offset, value);
      try {
        const Blob b = Blob::open_memory(forged.bytes());
        const auto view = open_structure(b, "nanocube");
        std::mt19937_64 q(k);
        for (int i = 0; i < 8; ++i) {
          const EventSelection sel = random_selection(q, b.event_table(), 8);
          view->events()->count(sel);
          view->events()->tiles(sel, 5);
          view->events()->topk(sel, "kind", 3);
          view->events()->series(sel, 86400);
        }
      } catch (const BlobError&) {
        ++refused;
      }
    }
  }
  EXPECT_GT(refused, tried / 4);
}

TEST(Nanocube, BadRequestsThrowOneLine) {
  const Opened o(cube_blob(generated_table(300, 5), "max-level=6"));
  EventSelection s;
  s.where = {{"nope", {"x"}}};
  EXPECT_THROW(o.cube().count(s), std::invalid_argument);
  EXPECT_THROW(o.cube().tiles({}, 7), std::invalid_argument);
  EXPECT_THROW(o.cube().series({}, 1800), std::invalid_argument);
  EXPECT_THROW(o.cube().topk({}, "nope", 3), std::invalid_argument);
  EventSelection tile;
  tile.tile = std::array<std::uint32_t, 3>{3, 8, 0};
  EXPECT_THROW(o.cube().count(tile), std::invalid_argument);
}

TEST(EventTable, TimesParse) {
  EXPECT_EQ(parse_event_time("2001-01-01T00:01Z"), 978307260);
  EXPECT_EQ(parse_event_time("2001-01-01T00:01:30Z"), 978307290);
  EXPECT_EQ(parse_event_time("2001-01-01T02:01+02:00"), 978307260);
  EXPECT_EQ(parse_event_time("2000-12-31T19:01-0500"), 978307260);
  EXPECT_EQ(parse_event_time("978307260"), 978307260);
  EXPECT_EQ(parse_event_time("2001-01-01"), 978307200);
  EXPECT_FALSE(parse_event_time("2001-02-30T00:00Z"));
  EXPECT_FALSE(parse_event_time("2001-01-01T00:00"));  // no zone
  EXPECT_FALSE(parse_event_time("yesterday"));
  EXPECT_EQ(format_event_time(978307260), "2001-01-01T00:01Z");
  EXPECT_EQ(edge_labels({-INFINITY, 0, 15, 60, INFINITY}),
            (std::vector<std::string>{"<0", "0..15", "15..60", ">=60"}));
}

EventColumns flight_columns() {
  EventColumns c;
  c.lat = "origin_lat", c.lon = "origin_lon", c.time = "time";
  c.categories = {parse_event_category("origin"),
                  parse_event_category("delay=delay_min:-inf,0,15,60,inf")};
  return c;
}

std::string import_error(const std::string& csv, EventColumns columns = flight_columns()) {
  try {
    read_event_csv("t.csv", csv, columns);
  } catch (const ImportError& e) {
    return e.what();
  }
  return "";
}

TEST(EventTable, BadRowsNameFileLineAndColumn) {
  const std::string header = "time,origin,delay_min,origin_lat,origin_lon\n";
  const std::string good = "2001-01-01T00:01Z,ORD,5,41.9,-87.9\n";
  EXPECT_EQ(import_error(header + good + "2001-13-01T00:01Z,ORD,5,41.9,-87.9\n"),
            "t.csv:3: column 'time': '2001-13-01T00:01Z' is not a time (ISO 8601 with Z or an "
            "offset, or Unix seconds)");
  EXPECT_EQ(import_error(header + good + "2001-01-01T00:01Z,ORD,late,41.9,-87.9\n"),
            "t.csv:3: column 'delay_min': 'late' is not a number");
  EXPECT_EQ(import_error(header + "2001-01-01T00:01Z,ORD,5,41.9\n"),
            "t.csv:2: 4 fields, expected at least 5");
  EXPECT_EQ(import_error(header + "2001-01-01T00:01Z,ORD,5,x,-87.9\n"),
            "t.csv:2: column 'origin_lat': 'x' is not a latitude in [-90, 90]");
  EXPECT_EQ(import_error("time,origin,delay_min,origin_lon\n" + good),
            "t.csv:1: no column 'origin_lat' (named by --lat)");
  EventColumns skip = flight_columns();
  skip.skip_invalid = true;
  const EventTable t = read_event_csv("t.csv", header + good + "bad,ORD,5,1,1\n" + good, skip);
  EXPECT_EQ(t.rows(), 2u);
  EXPECT_EQ(t.rows_skipped, 1u);
  EXPECT_THROW(parse_event_category("d=delay:1,0"), std::invalid_argument);
}

TEST(EventTable, CliBuildsQueriesAndRefusesBadInput) {
  test::TempDir dir;
  const std::string csv = dir.path().string() + "/e.csv", blob = dir.path().string() + "/e.kiln";
  test::write_text(csv,
                   "time,origin,delay_min,origin_lat,origin_lon\n"
                   "2001-01-01T00:01Z,ORD,5,41.9,-87.9\n2001-01-01T03:00Z,ATL,20,33.6,-84.4\n"
                   "2001-01-02T00:00Z,ORD,70,41.9,-87.9\n");
  const std::string flags =
      " --lat origin_lat --lon origin_lon --time time --time-bin 1h "
      "--category origin --category delay=delay_min:-inf,0,15,60,inf";
  auto r = test::run_kiln("build " + test::quoted(csv) + " -o " + test::quoted(blob) +
                          " --accel nanocube" + flags);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  test::write_text(dir.path().string() + "/q.jsonl",
                   "{\"where\": {\"origin\": [\"ORD\"]}}\n"
                   "{\"time\": [\"2001-01-01T00:00Z\", \"2001-01-01T06:00Z\"], \"k\": 1, \"by\": "
                   "\"origin\"}\n");
  r = test::run_kiln("query " + test::quoted(blob) + " --op count --in " +
                     test::quoted(dir.path().string() + "/q.jsonl") + " --out " +
                     test::quoted(dir.path().string() + "/a.jsonl"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(
      test::read_text(dir.path().string() + "/a.jsonl"),
      "{\"count\":2}\n{\"count\":2,\"time\":[\"2001-01-01T00:00Z\",\"2001-01-01T06:00Z\"]}\n");
  r = test::run_kiln("query " + test::quoted(blob) + " --op topk --in " +
                     test::quoted(dir.path().string() + "/q.jsonl") + " --out " +
                     test::quoted(dir.path().string() + "/a.jsonl"));
  EXPECT_EQ(r.exit_code, 1);  // the first line has no "by"
  EXPECT_EQ(r.err, "kiln query: " + dir.path().string() + "/q.jsonl:1: 'topk' needs \"by\"\n");
  r = test::run_kiln("render " + test::quoted(blob) + " -o " +
                     test::quoted(dir.path().string() + "/map.png") + " --where origin=ORD");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("2 events"), std::string::npos) << r.out;
  EXPECT_EQ(test::read_text(dir.path().string() + "/map.png").substr(1, 3), "PNG");
  test::write_text(csv, "time,origin,delay_min,origin_lat,origin_lon\nsoon,ORD,5,41.9,-87.9\n");
  r = test::run_kiln("build " + test::quoted(csv) + " -o " + test::quoted(blob) +
                     " --accel nanocube" + flags);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "kiln build: " + csv +
                       ":2: column 'time': 'soon' is not a time (ISO 8601 with Z or an offset, "
                       "or Unix seconds)\n");
}

// The first `rows` data rows of a .zst CSV (with its header), inflated only as far as needed.
std::string first_rows(const std::string& path, std::size_t rows) {
  std::ifstream in(path, std::ios::binary);
  std::string text, chunk(1 << 16, '\0'), out(1 << 18, '\0');
  ZSTD_DCtx* ctx = ZSTD_createDCtx();
  std::size_t lines = 0;
  while (lines <= rows && in.read(chunk.data(), std::streamsize(chunk.size())).gcount() > 0) {
    ZSTD_inBuffer input{chunk.data(), std::size_t(in.gcount()), 0};
    while (input.pos < input.size && lines <= rows) {
      ZSTD_outBuffer output{out.data(), out.size(), 0};
      if (ZSTD_isError(ZSTD_decompressStream(ctx, &output, &input))) break;
      for (std::size_t i = 0; i < output.pos && lines <= rows; ++i) {
        text += out[i];
        lines += out[i] == '\n';
      }
    }
  }
  ZSTD_freeDCtx(ctx);
  return text;
}

TEST(Nanocube, FlightsSliceAgreesWithBruteForce) {
  if (!std::filesystem::exists(kFlights)) GTEST_SKIP() << kEvents << " is absent";
  const EventTable table =
      read_event_csv("flights-100k.csv", first_rows(kFlights, 100000), flight_columns());
  ASSERT_EQ(table.rows(), 100000u);
  const Opened o(cube_blob(table, "max-level=20,time-bin=1h"));
  const auto& grid = static_cast<const NanocubeView&>(o.cube()).grid();
  EXPECT_GT(expect_agreement(o.cube(), *o.scan, o.blob.event_table(), grid, 1000, 11), 500u);
}

// MANIFEST.md's counts, on the whole file, once (about 6 s in a release build).
TEST(Nanocube, FlightsManifestCounts) {
  if (!std::filesystem::exists(kFlights)) GTEST_SKIP() << kEvents << " is absent";
  EventColumns columns = flight_columns();
  columns.categories[1] = parse_event_category("late=delay_min:-inf,16,inf");  // > 15 (minutes)
  const Scene scene = import_events(kFlights, columns, {});
  ASSERT_EQ(scene.events->rows(), 3000000u);
  EXPECT_EQ(scene.events->categories[0].labels.size(), 229u);
  EXPECT_EQ(
      format_event_time(*std::min_element(scene.events->times.begin(), scene.events->times.end())),
      "2001-01-01T00:01Z");
  EXPECT_EQ(
      format_event_time(*std::max_element(scene.events->times.begin(), scene.events->times.end())),
      "2001-07-01T00:00Z");
  const Opened o(test::blob_with(scene, "nanocube", 2));
  const EventQueries& cube = o.cube();
  EventSelection ord, late, west;
  ord.where = {{"origin", {"ORD"}}};
  late.where = {{"late", {">=16"}}};
  west.box = format::Box2d{{-124.5, 32.5}, {-114.0, 42.0}};
  west.time = std::array<std::int64_t, 2>{978307200, 978307200 + 31 * 86400};
  EXPECT_EQ(cube.count({}), 3000000u);
  EXPECT_EQ(cube.count(ord), 166341u);
  EXPECT_EQ(cube.count(late), 599055u);
  EXPECT_EQ(cube.count(west), 76088u);
  EXPECT_EQ(o.scan->count(west), 76088u);
}

// Topkube's rankings over time: a top-k over an interval walks the stored block rankings. Random
// intervals (hours to the whole range, some aligned to the blocks), boxes, tiles and filters:
// every answer equals the scan's, and the walk over block rankings answers most of them.
struct TopkTally {
  std::size_t queries = 0, walked = 0, with_blocks = 0;
};

EventSelection interval_selection(std::mt19937_64& rng, const EventTableView& t,
                                  const EventGrid& grid, std::size_t i) {
  std::uniform_real_distribution<double> u(0, 1);
  EventSelection s;
  const std::int64_t span = t.time_max - t.time_min, bin = grid.time_bin;
  const std::int64_t lengths[] = {3 * bin, 7 * 86400, 30 * 86400, span / 2, 64 * bin};
  const std::int64_t length = lengths[i % 5];
  std::int64_t t0 = t.time_min + std::int64_t(u(rng) * double(span - std::min(span, length)));
  if (i % 3 == 0) t0 = grid.time_origin + (t0 - grid.time_origin) / (32 * bin) * (32 * bin);
  s.time = std::array<std::int64_t, 2>{t0, t0 + length};
  const auto& p = t.points[std::size_t(u(rng) * double(t.rows())) % t.rows()];
  if (i % 4 == 1) {
    const double w = std::pow(10.0, -1 + 2.5 * u(rng));
    s.box = format::Box2d{{p.x - w, p.y - w}, {p.x + w, p.y + w}};
  }
  if (i % 7 == 2) s.where.emplace_back(t.categories[1].name, std::vector<std::string>{">=60"});
  if (i % 11 == 3)
    s.where.emplace_back(
        t.categories[0].name,
        std::vector<std::string>{std::string(t.label(0, 0)), std::string(t.label(0, 3))});
  return s;
}

TopkTally expect_interval_topk(const NanocubeView& cube, const EventQueries& reference,
                               const std::string& by, std::size_t queries, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  TopkTally tally;
  for (std::size_t i = 0; i < queries; ++i) {
    const EventSelection s = interval_selection(rng, cube.table(), cube.grid(), i);
    const std::size_t k = 1 + rng() % 10;
    NanocubeView::TopkTrace trace;
    const auto top = cube.topk_traced(s, by, k, trace);
    EXPECT_TRUE(same_topk(top, reference.topk(s, by, k))) << "query " << i;
    if (::testing::Test::HasFailure()) break;
    ++tally.queries;
    tally.walked += trace.path == NanocubeView::TopkTrace::Path::kThreshold;
    tally.with_blocks += trace.block_lists > 0;
  }
  return tally;
}

TEST(Nanocube, TimeRankedTopkAgreesWithBruteForceAndWalksBlocks) {
  const EventTable table = generated_table(6000, 21);
  const Opened o(cube_blob(table, "max-level=12,time-bin=1h,topk-min-events=64,topk-min-labels=8"));
  const auto& cube = static_cast<const NanocubeView&>(o.cube());
  ASSERT_GT(cube.block_levels(), 2u);
  EXPECT_TRUE(cube.block_rankings_consistent());
  const TopkTally tally = expect_interval_topk(cube, *o.scan, "kind", 1500, 5);
  EXPECT_EQ(tally.queries, 1500u);
  EXPECT_GT(tally.with_blocks, tally.queries / 3) << tally.walked;
  // A month over the whole map: block rankings, a few of the 40 labels counted exactly.
  EventSelection month;
  month.time = std::array<std::int64_t, 2>{978307200 + 5 * 86400 + 7200, 978307200 + 35 * 86400};
  NanocubeView::TopkTrace trace;
  EXPECT_TRUE(same_topk(cube.topk_traced(month, "kind", 3, trace), o.scan->topk(month, "kind", 3)));
  EXPECT_EQ(trace.path, NanocubeView::TopkTrace::Path::kThreshold);
  EXPECT_GT(trace.block_lists, 1u);
  EXPECT_LT(trace.labels_counted, 20u) << "the block rankings should rule out most labels";
  // The delay category has 4 labels: counted, never walked.
  expect_interval_topk(cube, *o.scan, "delay", 200, 6);
}

// The same on the 100,000-row flights slice (hourly bins, the CLI's defaults).
TEST(Nanocube, FlightsSliceTimeRankedTopkAgreesWithBruteForce) {
  if (!std::filesystem::exists(kFlights)) GTEST_SKIP() << kEvents << " is absent";
  const EventTable table =
      read_event_csv("flights-100k.csv", first_rows(kFlights, 100000), flight_columns());
  const Opened o(cube_blob(table, "max-level=16,time-bin=1h"));
  const auto& cube = static_cast<const NanocubeView&>(o.cube());
  EXPECT_TRUE(cube.block_rankings_consistent());
  const TopkTally tally = expect_interval_topk(cube, *o.scan, "origin", 400, 8);
  EXPECT_EQ(tally.queries, 400u);
  EXPECT_GT(tally.with_blocks, tally.queries / 4) << tally.walked;
}

// Forged block rankings: every byte changed in NCBI, NCBL or NCBE is refused at open or by
// verify's recount; where open accepts it, interval top-k queries stay in range (ASan).
TEST(Nanocube, ForgedBlockRankingsAreRefusedOrSafe) {
  const EventTable table = generated_table(1500, 22);
  const auto blob =
      cube_blob(table, "max-level=8,time-bin=1h,topk-min-events=64,topk-min-labels=8");
  const AlignedBuffer original = test::aligned_copy(blob);
  const Blob clean = Blob::open_memory(original.bytes());
  std::mt19937_64 rng(23);
  std::size_t tried = 0, refused = 0;
  for (std::uint32_t s = 1; s < clean.sections().size(); ++s) {
    const std::uint32_t kind = clean.sections()[s].kind;
    if (kind != format::kSectionNanocubeBlockIndex && kind != format::kSectionNanocubeBlockLists &&
        kind != format::kSectionNanocubeBlockEntries)
      continue;
    const std::uint64_t size = clean.sections()[s].raw_size;
    for (int k = 0; k < 40 && size > 0; ++k) {
      const std::size_t offset = rng() % size;
      const std::byte value{std::uint8_t(1 + rng() % 255)};
      const AlignedBuffer forged = test::forged_copy(blob, s, offset, value);
      if (std::equal(forged.bytes().begin(), forged.bytes().end(), original.bytes().begin()))
        continue;  // the byte already had that value
      ++tried;
      try {
        const Blob b = Blob::open_memory(forged.bytes());
        const auto view = open_structure(b, "nanocube");
        std::mt19937_64 q(k);
        const auto& cube = static_cast<const NanocubeView&>(*view->events());
        for (std::size_t i = 0; i < 10; ++i)
          view->events()->topk(interval_selection(q, b.event_table(), cube.grid(), i), "kind", 3);
        b.verify();
        ADD_FAILURE() << "accepted: section " << s << " byte " << offset;
      } catch (const BlobError&) {
        ++refused;
      }
    }
  }
  ASSERT_GT(tried, 60u);
  EXPECT_EQ(refused, tried);
}

// All-time rankings may share a range (a node with one child) but not overlap: lists forged to
// name shifted windows of one long list (which, read one by one, would cost lists x entries at
// open) are refused.
TEST(Nanocube, OverlappingRankingsAreRefused) {
  const EventTable table = generated_table(1500, 22);
  const auto blob = cube_blob(table, "max-level=8,time-bin=1h");
  const AlignedBuffer original = test::aligned_copy(blob);
  const Blob clean = Blob::open_memory(original.bytes());
  std::uint32_t lists_section = 0;
  for (std::uint32_t s = 1; s < clean.sections().size(); ++s)
    if (clean.sections()[s].kind == format::kSectionNanocubeRankLists) lists_section = s;
  ASSERT_NE(lists_section, 0u);
  const auto lists = clean.section_view<format::NanocubeRankList>(lists_section);
  std::size_t longest = 0;
  for (std::size_t i = 0; i < lists.size(); ++i)
    if (lists[i].count > lists[longest].count) longest = i;
  ASSERT_GE(lists[longest].count, 3u);
  ASSERT_GE(lists.size(), 2u);
  // Another list made to start one entry inside the longest one.
  format::NanocubeRankList forged = lists[longest];
  forged.first += 1, forged.count -= 1;
  const std::size_t victim = longest == 0 ? 1 : 0;
  const AlignedBuffer bytes =
      test::forged_copy(blob, lists_section, victim * sizeof(format::NanocubeRankList), forged);
  EXPECT_THROW(open_structure(Blob::open_memory(bytes.bytes()), "nanocube"), BlobError);
  // The same range as the longest one is a shared list, not an overlap: no refusal for that.
  const AlignedBuffer shared = test::forged_copy(
      blob, lists_section, victim * sizeof(format::NanocubeRankList), lists[longest]);
  try {
    const Blob b = Blob::open_memory(shared.bytes());
    open_structure(b, "nanocube");
  } catch (const BlobError& e) {
    EXPECT_EQ(std::string(e.what()).find("overlaps"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace kiln
