// The bucket PR quadtree against brute force (range, k nearest, radius; ties and duplicates) on
// generated points and the ZIP code points; coincident points, cells, determinism across
// thread counts, forged nodes.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/csv_reader.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/compiler/quadtree_builder.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/quadtree.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

using format::Box2d;
using format::Double2;

const std::string kZipCodes = KILN_MESH_DIR "/../geo/zipcodes.csv.zst";

struct Built {
  FlatQuadtree flat;
  std::size_t table_points;
  QuadtreeView view() const {
    return QuadtreeView(flat.nodes, flat.points, flat.ids, flat.root, table_points);
  }
};

Built build(std::span<const Double2> points, std::uint32_t bucket = 8, std::uint32_t depth = 32,
            unsigned threads = 0) {
  QuadtreeBuildOptions o;
  o.bucket_size = bucket;
  o.max_depth = depth;
  o.threads = threads;
  return {build_quadtree(points, o), points.size()};
}

std::vector<std::uint32_t> brute_range(std::span<const Double2> points, const Box2d& box) {
  std::vector<std::uint32_t> out;
  for (std::uint32_t i = 0; i < points.size(); ++i)
    if (box.contains(points[i])) out.push_back(i);
  return out;
}

std::vector<Neighbor2> brute_sorted(std::span<const Double2> points, const Double2& q) {
  std::vector<Neighbor2> all(points.size());
  for (std::uint32_t i = 0; i < points.size(); ++i)
    all[i] = {format::distance_squared(points[i], q), i};
  std::sort(all.begin(), all.end(), [](const Neighbor2& a, const Neighbor2& b) {
    return a.distance_squared < b.distance_squared ||
           (a.distance_squared == b.distance_squared && a.index < b.index);
  });
  return all;
}

// Boxes of every shape the issue lists: empty (inverted), tiny, the whole extent, degenerate
// lines and points, boxes outside the points, and random ones of every size.
std::vector<Box2d> sample_boxes(std::span<const Double2> points, std::size_t count,
                                std::uint32_t seed) {
  std::mt19937 rng(seed);
  Box2d b;
  for (const auto& p : points) b.grow(p);
  const double w = std::max(b.max.x - b.min.x, 1e-9), h = std::max(b.max.y - b.min.y, 1e-9);
  std::uniform_real_distribution<double> unit(0, 1);
  std::uniform_int_distribution<std::size_t> pick(0, points.size() - 1);
  auto x_at = [&](double t) { return b.min.x - 0.25 * w + 1.5 * w * t; };
  auto y_at = [&](double t) { return b.min.y - 0.25 * h + 1.5 * h * t; };
  std::vector<Box2d> boxes{b,
                           {{b.min.x - w, b.min.y - h}, {b.max.x + w, b.max.y + h}},
                           {{b.max.x + 1, b.min.y}, {b.max.x + 2, b.max.y}},  // outside
                           {{1, 1}, {0, 0}},                                  // inverted
                           {{b.min.x, b.min.y}, {b.min.x, b.max.y}}};         // a line
  while (boxes.size() < count) {
    const std::size_t kind = boxes.size() % 5;
    const Double2 p = points[pick(rng)];
    if (kind == 0) {  // a point's own degenerate box
      boxes.push_back({p, p});
    } else if (kind == 1) {  // a vertical or horizontal line through a point
      boxes.push_back(unit(rng) < 0.5 ? Box2d{{p.x, b.min.y}, {p.x, b.max.y}}
                                      : Box2d{{b.min.x, p.y}, {b.max.x, p.y}});
    } else if (kind == 2) {  // tiny, around a point
      const double r = 1e-4 * w * unit(rng);
      boxes.push_back({{p.x - r, p.y - r}, {p.x + r, p.y + r}});
    } else {
      const double s = kind == 3 ? 0.05 : 0.6;
      const double x = x_at(unit(rng)), y = y_at(unit(rng));
      boxes.push_back({{x, y}, {x + s * w * unit(rng), y + s * h * unit(rng)}});
    }
  }
  return boxes;
}

// Queries on points (zero distances, duplicates), near them, and anywhere around the bounds.
std::vector<Double2> sample_queries(std::span<const Double2> points, std::size_t count,
                                    std::uint32_t seed) {
  std::mt19937 rng(seed);
  Box2d b;
  for (const auto& p : points) b.grow(p);
  const double w = std::max(b.max.x - b.min.x, 1e-9), h = std::max(b.max.y - b.min.y, 1e-9);
  std::uniform_real_distribution<double> unit(0, 1), jitter(-0.01, 0.01);
  std::uniform_int_distribution<std::size_t> pick(0, points.size() - 1);
  std::vector<Double2> queries;
  for (std::size_t i = 0; i < count; ++i) {
    const Double2 p = points[pick(rng)];
    if (i % 3 == 0)
      queries.push_back(p);
    else if (i % 3 == 1)
      queries.push_back({p.x + jitter(rng) * w, p.y + jitter(rng) * h});
    else
      queries.push_back({b.min.x - w + 3 * w * unit(rng), b.min.y - h + 3 * h * unit(rng)});
  }
  return queries;
}

void expect_matches_brute_force(std::span<const Double2> points, const QuadtreeView& tree,
                                std::size_t count, const std::string& what) {
  std::vector<std::uint32_t> found;
  for (const Box2d& box : sample_boxes(points, count, 7)) {
    tree.range(box, found);
    ASSERT_EQ(found, brute_range(points, box))
        << what << " box " << box.min.x << "," << box.min.y << "," << box.max.x << "," << box.max.y;
    Cost cost;
    std::vector<std::uint32_t> counted;
    tree.range_counting(box, counted, cost);
    ASSERT_EQ(counted, found) << what;
  }
  Box2d b;
  for (const auto& p : points) b.grow(p);
  const double extent = std::max(b.max.x - b.min.x, b.max.y - b.min.y);
  for (const Double2& q : sample_queries(points, count / 2, 11)) {
    const std::vector<Neighbor2> all = brute_sorted(points, q);
    for (const std::size_t k : {std::size_t(1), std::size_t(7), std::size_t(40)}) {
      std::vector<Neighbor2> got(k);
      const std::size_t n = tree.nearest(q, got);
      const std::size_t want = std::min(k, all.size());
      ASSERT_EQ(n, want) << what;
      got.resize(n);
      ASSERT_EQ(got, std::vector<Neighbor2>(all.begin(), all.begin() + std::ptrdiff_t(want)))
          << what << " k " << k << " at " << q.x << "," << q.y;
    }
    for (const double r : {0.0, 0.003 * extent, 0.05 * extent}) {
      std::vector<Neighbor2> got;
      tree.within_radius(q, r, got);
      std::vector<Neighbor2> want;
      for (const auto& n : all)
        if (n.distance_squared <= r * r) want.push_back(n);
      ASSERT_EQ(got, want) << what << " radius " << r;
    }
  }
}

std::vector<Double2> uniform_points(std::size_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> x(-180, 180), y(-90, 90);
  std::vector<Double2> points(n);
  for (auto& p : points) p = {x(rng), y(rng)};
  return points;
}

// Clusters, exact duplicates and a lattice (many equal distances: ties by index).
std::vector<Double2> awkward_points(std::size_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> cluster(0, 0.001);
  std::vector<Double2> points;
  for (std::size_t i = 0; points.size() < n; ++i) {
    if (i % 4 == 0)
      points.push_back({double(i % 37), double((i / 37) % 23)});  // lattice
    else if (i % 4 == 1 && !points.empty())
      points.push_back(points[(i * 7919) % points.size()]);
    else
      points.push_back({10 + cluster(rng), 5 + cluster(rng)});
  }
  return points;
}

std::vector<Double2> zip_points() {
  const ImportLimits limits;
  const auto input = read_input_bytes(kZipCodes, limits);
  CsvReader csv(kZipCodes, std::string_view(reinterpret_cast<const char*>(input.bytes.data()),
                                            input.bytes.size()));
  std::vector<std::string_view> fields;
  EXPECT_TRUE(csv.next(fields));
  const auto lat = csv_column(fields, "latitude"), lon = csv_column(fields, "longitude");
  EXPECT_TRUE(lat && lon);
  std::vector<Double2> points;
  while (csv.next(fields))
    points.push_back({std::stod(std::string(fields[*lon])), std::stod(std::string(fields[*lat]))});
  return points;
}

TEST(Quadtree, MatchesBruteForceOnUniformPoints) {
  const auto points = uniform_points(5000, 1);
  for (const std::uint32_t bucket : {1u, 8u, 64u})
    expect_matches_brute_force(points, build(points, bucket).view(), 300,
                               "uniform, bucket " + std::to_string(bucket));
  // Answers of 10^3-10^4 points among 1.2 * 10^5: both long-answer sorts (radix and bitmap).
  const auto many = uniform_points(120000, 6);
  expect_matches_brute_force(many, build(many, 32).view(), 40, "uniform, 120k");
}

TEST(Quadtree, MatchesBruteForceWithTiesAndDuplicates) {
  const auto points = awkward_points(4000, 2);
  expect_matches_brute_force(points, build(points, 4).view(), 300, "awkward");
  expect_matches_brute_force(points, build(points, 4, 3).view(), 200, "awkward, depth 3");
}

TEST(Quadtree, MatchesBruteForceOnZipCodes) {
  if (!std::filesystem::exists(kZipCodes))
    GTEST_SKIP() << kZipCodes << " is absent (../shared): ZIP code test skipped";
  const auto points = zip_points();
  ASSERT_EQ(points.size(), 42049u);
  expect_matches_brute_force(points, build(points).view(), 400, "zip codes");
}

TEST(Quadtree, CoincidentPointsMakeOneLeaf) {
  const std::vector<Double2> same(10000, Double2{3.5, -2.25});
  const Built t = build(same, 4);
  EXPECT_EQ(t.flat.nodes.size(), 1u);
  EXPECT_EQ(t.flat.stats.largest_bucket, 10000u);
  std::vector<Double2> near(same);
  near[17].x = std::nextafter(3.5, 4.0);  // one point apart by one ulp: stops at max-depth
  const Built n = build(near, 4, 20);
  EXPECT_EQ(n.flat.stats.depth, 20u);
  expect_matches_brute_force(near, n.view(), 50, "near-coincident");
}

TEST(Quadtree, CellsCoverEveryPointOnce) {
  const auto points = awkward_points(3000, 3);
  const Built t = build(points, 6);
  std::vector<IndexCell2> cells;
  t.view().cells(cells);
  EXPECT_EQ(cells.size(), t.flat.stats.leaf_count);
  std::size_t first = 0;
  for (const IndexCell2& c : cells) {
    for (std::size_t i = first; i < first + c.items; ++i)
      EXPECT_TRUE(c.box.contains(t.flat.points[i]));
    EXPECT_LE(c.level, t.flat.stats.depth);
    first += c.items;
  }
  EXPECT_EQ(first, points.size());
}

TEST(Quadtree, IdenticalForAnyThreadCount) {
  const auto points = uniform_points(200000, 4);
  const Built one = build(points, 8, 32, 1);
  for (const unsigned threads : {2u, 8u}) {
    const Built other = build(points, 8, 32, threads);
    ASSERT_EQ(other.flat.nodes.size(), one.flat.nodes.size());
    EXPECT_EQ(std::memcmp(other.flat.nodes.data(), one.flat.nodes.data(),
                          one.flat.nodes.size() * sizeof(format::QuadNode)),
              0);
    EXPECT_EQ(other.flat.ids, one.flat.ids);
  }
}

TEST(Quadtree, RefusesBadInput) {
  const std::vector<Double2> none;
  EXPECT_THROW(build(none), std::invalid_argument);
  const std::vector<Double2> nan{{0, 0}, {std::nan(""), 1}};
  EXPECT_THROW(build(nan), std::invalid_argument);
  const std::vector<Double2> one{{1, 2}};
  EXPECT_THROW(build(one, 0), std::invalid_argument);
  EXPECT_THROW(build(one, 8, format::kQuadMaxDepth + 1), std::invalid_argument);
}

// Every forged node either fails the view's walk or leaves queries in range (ASan watches).
TEST(Quadtree, ForgedNodesAreRefusedOrSafe) {
  const auto points = awkward_points(600, 5);
  const Built t = build(points, 3);
  std::mt19937 rng(9);
  const auto queries = sample_queries(points, 8, 13);
  const auto boxes = sample_boxes(points, 8, 17);
  std::size_t refused = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    auto nodes = t.flat.nodes;
    auto ids = t.flat.ids;
    auto* words = reinterpret_cast<std::uint32_t*>(nodes.data());
    const std::size_t word = rng() % (nodes.size() * 3);
    words[word] = trial % 3 == 0 ? std::uint32_t(rng()) : words[word] ^ (1u << (rng() % 32));
    if (trial % 50 == 0) ids[rng() % ids.size()] = std::uint32_t(rng());
    try {
      const QuadtreeView view(nodes, t.flat.points, ids, t.flat.root, points.size());
      std::vector<std::uint32_t> found;
      std::vector<Neighbor2> near(5);
      for (const auto& box : boxes) view.range(box, found);
      for (const auto& q : queries) {
        view.nearest(q, near);
        view.within_radius(q, 3.0, near);
      }
      std::vector<IndexCell2> cells;
      view.cells(cells);
      for (const auto id : found) ASSERT_LT(id, points.size());
    } catch (const BlobError&) {
      refused += 1;
    }
  }
  EXPECT_GT(refused, 1000u);
}

// A point table of `n` rows as a CSV reader makes it, with feature_points when `multipoint`
// (row r owns r % 3 points: some rows none).
Scene point_scene(std::size_t n, bool multipoint, std::uint32_t seed) {
  Scene scene;
  PointTable2 table;
  table.points = awkward_points(n, seed);
  if (multipoint) {
    std::size_t next = 0;
    table.feature_points = {0};
    for (std::size_t r = 0; next < table.points.size(); ++r) {
      next = std::min(table.points.size(), next + r % 3);
      table.feature_points.push_back(next);
    }
  }
  for (const auto& p : table.points) table.bounds.grow(p);
  table.x_column = "x", table.y_column = "y";
  scene.points2 = std::move(table);
  return scene;
}

void expect_blob_answers(const Blob& blob, std::span<const Double2> points,
                         const std::string& what) {
  const auto view = open_structure(blob, "quadtree");
  const Point2Queries* q = view->points2();
  ASSERT_NE(q, nullptr);
  std::vector<std::uint32_t> found;
  for (const Box2d& box : sample_boxes(points, 60, 3)) {
    q->range(box, found);
    ASSERT_EQ(found, brute_range(points, box)) << what;
  }
  for (const Double2& p : sample_queries(points, 30, 5)) {
    std::vector<Neighbor2> got(5);
    got.resize(q->nearest(p, got));
    const auto all = brute_sorted(points, p);
    ASSERT_EQ(got, std::vector<Neighbor2>(all.begin(), all.begin() + 5)) << what;
  }
}

TEST(QuadtreeBlob, RoundTripsThroughFileMemoryAndZstd) {
  const Scene scene = point_scene(3000, false, 21);
  const auto& points = scene.points2->points;
  for (const bool compress : {false, true}) {
    const auto bytes = test::blob_with(scene, "quadtree:bucket-size=6", 0, compress);
    const AlignedBuffer copy = test::aligned_copy(bytes);
    const Blob memory = Blob::open_memory(copy.bytes());
    memory.verify();
    expect_blob_answers(memory, points, compress ? "zstd" : "memory");
    test::TempDir dir;
    test::write_file(dir.file("p.kiln"), bytes);
    const Blob file = Blob::open_file(dir.file("p.kiln"));
    file.verify();
    expect_blob_answers(file, points, "file");
  }
}

TEST(QuadtreeBlob, ByteIdenticalOnOneTwoEightThreads) {
  const Scene scene = point_scene(120000, true, 22);
  const auto one = test::blob_with(scene, "quadtree", 1);
  EXPECT_EQ(test::blob_with(scene, "quadtree", 2), one);
  EXPECT_EQ(test::blob_with(scene, "quadtree", 8), one);
}

// Every byte of every quadtree section forged, a sample of values each: open and verify refuse
// it with a BlobError, or every query stays in range.
TEST(QuadtreeBlob, ForgedSectionsAreRefusedOrSafe) {
  const Scene scene = point_scene(400, false, 23);
  const auto bytes = test::blob_with(scene, "quadtree:bucket-size=3", 1);
  const AlignedBuffer clean = test::aligned_copy(bytes);
  const Blob blob = Blob::open_memory(clean.bytes());
  const auto boxes = sample_boxes(scene.points2->points, 6, 1);
  const auto queries = sample_queries(scene.points2->points, 6, 2);
  std::size_t refused = 0, tried = 0;
  for (const std::uint32_t section : blob.structures()[0].sections) {
    const std::size_t size = blob.section_bytes(section).size();
    for (std::size_t offset = 0; offset < size; offset += 1 + offset % 7) {
      const std::uint8_t value = std::uint8_t(blob.section_bytes(section)[offset]) ^ 0x5Au;
      const AlignedBuffer forged = test::forged_copy(bytes, section, offset, value);
      tried += 1;
      try {
        const Blob f = Blob::open_memory(forged.bytes());
        const auto view = open_structure(f, "quadtree");
        std::vector<std::uint32_t> found;
        std::vector<Neighbor2> near(4);
        for (const auto& box : boxes) view->points2()->range(box, found);
        for (const auto& q : queries) view->points2()->nearest(q, near);
        for (const auto id : found) ASSERT_LT(id, scene.points2->points.size());
        f.verify();
      } catch (const BlobError&) {
        refused += 1;
      }
    }
  }
  EXPECT_GT(refused, tried / 4);
}

TEST(QuadtreeBlob, DumpVerifyAndQueryOnTheCommandLine) {
  const Scene scene = point_scene(2000, true, 24);
  test::TempDir dir;
  const std::string blob = dir.file("p.kiln");
  test::write_file(blob, test::blob_with(scene, "quadtree", 0));
  const auto dump = test::run_kiln("dump --json " + test::quoted(blob));
  ASSERT_EQ(dump.exit_code, 0) << dump.err;
  EXPECT_NE(dump.out.find("\"levels\""), std::string::npos);
  EXPECT_NE(dump.out.find("\"bytes_per_point\""), std::string::npos);
  const auto verify = test::run_kiln("verify " + test::quoted(blob));
  EXPECT_EQ(verify.exit_code, 0) << verify.err;
  // Boxes as CSV with a header; answers are rows (features), once per box.
  const auto& t = *scene.points2;
  const auto boxes = sample_boxes(t.points, 40, 9);
  std::string csv = "min_x,min_y,max_x,max_y\n", want = "box_index,point_index\n";
  for (std::size_t b = 0; b < boxes.size(); ++b) {
    char line[160];
    std::snprintf(line, sizeof line, "%.17g,%.17g,%.17g,%.17g\n", boxes[b].min.x, boxes[b].min.y,
                  boxes[b].max.x, boxes[b].max.y);
    csv += line;
    for (std::size_t row = 0; row + 1 < t.feature_points.size(); ++row)
      for (auto i = t.feature_points[row]; i < t.feature_points[row + 1]; ++i)
        if (boxes[b].contains(t.points[i])) {
          want += std::to_string(b) + "," + std::to_string(row) + "\n";
          break;
        }
  }
  test::write_text(dir.file("boxes.csv"), csv);
  const auto range = test::run_kiln("query " + test::quoted(blob) + " --op range --in " +
                                    test::quoted(dir.file("boxes.csv")) + " --out " +
                                    test::quoted(dir.file("out.csv")) + " --threads 2");
  ASSERT_EQ(range.exit_code, 0) << range.err;
  EXPECT_EQ(test::read_text(dir.file("out.csv")), want);
  // knn2d from binary float64 pairs: k rows per query, the first at distance 0 for a table point.
  const std::vector<double> xy{t.points[5].x, t.points[5].y};
  test::write_file(dir.file("q.bin"), std::as_bytes(std::span(xy)));
  const auto knn = test::run_kiln("query " + test::quoted(blob) + " --op knn2d --k 3 --in " +
                                  test::quoted(dir.file("q.bin")) + " --out " +
                                  test::quoted(dir.file("knn.csv")));
  ASSERT_EQ(knn.exit_code, 0) << knn.err;
  const std::string knn_text = test::read_text(dir.file("knn.csv"));
  EXPECT_EQ(std::count(knn_text.begin(), knn_text.end(), '\n'), 4);
  EXPECT_EQ(knn_text.rfind("query_index,point_index,distance\n0,", 0), 0u) << knn_text;
  // radius2d 0 around the same point: every table point there (duplicates included), distance 0.
  const auto radius = test::run_kiln(
      "query " + test::quoted(blob) + " --op radius2d --radius 0 --in " +
      test::quoted(dir.file("q.bin")) + " --out " + test::quoted(dir.file("radius.csv")));
  ASSERT_EQ(radius.exit_code, 0) << radius.err;
  const std::string radius_text = test::read_text(dir.file("radius.csv"));
  const auto at_five = std::count(t.points.begin(), t.points.end(), t.points[5]);
  EXPECT_GE(std::count(radius_text.begin(), radius_text.end(), '\n'), 2);
  EXPECT_LE(std::count(radius_text.begin(), radius_text.end(), '\n'), 1 + at_five);
  EXPECT_NE(radius_text.find(",0\n"), std::string::npos) << radius_text;
  test::write_text(dir.file("bad.csv"), "1,2,3\n");
  const auto bad = test::run_kiln("query " + test::quoted(blob) + " --op range --in " +
                                  test::quoted(dir.file("bad.csv")) + " --out " +
                                  test::quoted(dir.file("x.csv")));
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find("bad.csv:1:"), std::string::npos) << bad.err;
  const auto map =
      test::run_kiln("render " + test::quoted(blob) + " --mode cells --size 200x120 -o " +
                     test::quoted(dir.file("map.png")));
  EXPECT_EQ(map.exit_code, 0) << map.err;
  EXPECT_TRUE(std::filesystem::exists(dir.file("map.png")));
}

}  // namespace
}  // namespace kiln
