// The bucket PR quadtree against brute force (range, k nearest, radius; ties and duplicates) on
// generated points and the ZIP code points; coincident points, cells, determinism across
// thread counts, forged nodes.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>

#include "kiln/compiler/csv_reader.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/compiler/quadtree_builder.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/quadtree.hpp"
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
  std::vector<Box2d> boxes{b, {{b.min.x - w, b.min.y - h}, {b.max.x + w, b.max.y + h}},
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
        << what << " box " << box.min.x << "," << box.min.y << "," << box.max.x << ","
        << box.max.y;
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
    if (i % 4 == 0) points.push_back({double(i % 37), double((i / 37) % 23)});  // lattice
    else if (i % 4 == 1 && !points.empty()) points.push_back(points[(i * 7919) % points.size()]);
    else points.push_back({10 + cluster(rng), 5 + cluster(rng)});
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
    for (std::size_t i = first; i < first + c.items; ++i) EXPECT_TRUE(c.box.contains(t.flat.points[i]));
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

}  // namespace
}  // namespace kiln
