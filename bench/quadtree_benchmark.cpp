// Quadtree range queries against a brute-force scan and (with -DKILN_BENCH_GEO=ON) Boost.Geometry's
// R-tree (libboost-dev, benchmark only), single thread, on the same points and boxes; the
// quadtree's bucket size (range and k = 8 nearest) and its two point layouts
// (Double2 copies in leaf order, as stored, against ids only with coordinates read from the
// table), which chose the defaults.
//
// Usage: kiln_bench_quadtree [--rounds=N] [--queries=N] [ZIPCODES.csv[.zst]]
//   Data: the ZIP code points (longitude, latitude) when given, and 1,000,000 uniform random
//   points in their bounds (else in [-180, 180] x [-90, 90]). Boxes are centred on random data
//   points with sides 0.1 %, 1 % and 5 % of the bounds' width. Each measurement runs once per
//   round, methods alternating within a round; the median over rounds is printed.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <functional>
#include <map>
#include <memory>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "kiln/compiler/csv_reader.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/compiler/quadtree_builder.hpp"
#include "kiln/runtime/quadtree.hpp"

#ifdef KILN_BENCH_GEO
#include <boost/geometry.hpp>
#include <boost/geometry/index/rtree.hpp>
#endif

namespace {

using Clock = std::chrono::steady_clock;
using kiln::format::Box2d;
using kiln::format::Double2;

double seconds_of(const std::function<void()>& run) {
  const auto start = Clock::now();
  run();
  return std::chrono::duration<double>(Clock::now() - start).count();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

std::vector<Double2> read_zip_points(const std::string& path) {
  const auto input = kiln::read_input_bytes(path);
  kiln::CsvReader csv(path,
                      {reinterpret_cast<const char*>(input.bytes.data()), input.bytes.size()});
  std::vector<std::string_view> fields;
  csv.next(fields);
  const auto lat = kiln::csv_column(fields, "latitude"),
             lon = kiln::csv_column(fields, "longitude");
  std::vector<Double2> points;
  while (lat && lon && csv.next(fields))
    points.push_back({std::stod(std::string(fields[*lon])), std::stod(std::string(fields[*lat]))});
  return points;
}

Box2d bounds_of(const std::vector<Double2>& points) {
  Box2d b;
  for (const auto& p : points) b.grow(p);
  return b;
}

std::vector<Double2> uniform_points(std::size_t n, const Box2d& b, std::uint32_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> x(b.min.x, b.max.x), y(b.min.y, b.max.y);
  std::vector<Double2> points(n);
  for (auto& p : points) p = {x(rng), y(rng)};
  return points;
}

std::vector<Box2d> boxes_around(const std::vector<Double2>& points, double side, std::size_t count,
                                std::uint32_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<std::size_t> pick(0, points.size() - 1);
  std::vector<Box2d> boxes(count);
  for (auto& b : boxes) {
    const Double2 c = points[pick(rng)];
    b = {{c.x - side / 2, c.y - side / 2}, {c.x + side / 2, c.y + side / 2}};
  }
  return boxes;
}

// The quadtree's range walk, unsorted, reading coordinates from the leaf-order copies (the
// stored layout) or, with kIdsOnly, from the table through the ids: the layout a blob would
// have without the copies (4 bytes per point instead of 20; compared, not shipped).
template <bool kIdsOnly>
void range_walk(const kiln::QuadtreeView& tree, const std::vector<Double2>& table, const Box2d& box,
                std::vector<std::uint32_t>& out) {
  out.clear();
  const auto nodes = tree.nodes();
  const auto ids = tree.ids();
  struct P {
    std::uint32_t node;
    Box2d cell;
  };
  std::vector<P> stack{{0, tree.root()}};
  while (!stack.empty()) {
    const P p = stack.back();
    stack.pop_back();
    const auto& n = nodes[p.node];
    if (box.min.x <= p.cell.min.x && p.cell.max.x <= box.max.x && box.min.y <= p.cell.min.y &&
        p.cell.max.y <= box.max.y) {
      out.insert(out.end(), ids.begin() + n.first, ids.begin() + n.first + n.count);
    } else if (n.is_leaf()) {
      for (std::uint32_t i = n.first; i < n.first + n.count; ++i)
        if (box.contains(kIdsOnly ? table[ids[i]] : tree.points()[i])) out.push_back(ids[i]);
    } else {
      for (std::uint32_t c = p.node + 1; c < n.end(); c = nodes[c].end()) {
        const Box2d cell = kiln::format::quad_child_cell(p.cell, nodes[c].quadrant());
        if (cell.overlaps(box)) stack.push_back({c, cell});
      }
    }
  }
}

struct Bench {
  int rounds = 5;
  std::size_t queries = 20000;
  std::map<std::string, std::vector<double>> times;  // per label, one per round
  std::map<std::string, std::uint64_t> checks;       // results found, to compare methods

  // `run` does the work and returns the results it found; per-query seconds are recorded.
  void add(const std::string& label, std::size_t count, const std::function<std::uint64_t()>& run) {
    std::uint64_t found = 0;
    times[label].push_back(seconds_of([&] { found = run(); }) / double(count));
    checks[label] = found / count;
  }
};

#ifdef KILN_BENCH_GEO
namespace bg = boost::geometry;
namespace bgi = boost::geometry::index;
using BPoint = bg::model::point<double, 2, bg::cs::cartesian>;
using BBox = bg::model::box<BPoint>;
using RTree = bgi::rtree<std::pair<BPoint, std::uint32_t>, bgi::rstar<16>>;

// Packed (STR bulk load) through the range constructor: Boost's fastest build and queries.
std::unique_ptr<RTree> build_rtree(const std::vector<Double2>& points) {
  std::vector<std::pair<BPoint, std::uint32_t>> values;
  for (std::uint32_t i = 0; i < points.size(); ++i)
    values.push_back({BPoint(points[i].x, points[i].y), i});
  return std::make_unique<RTree>(values);
}

// The same answer as Kiln's: the indices in the box, ascending.
std::uint64_t rtree_range(const RTree& rtree, const std::vector<Box2d>& boxes) {
  std::vector<std::pair<BPoint, std::uint32_t>> hits;
  std::vector<std::uint32_t> found;
  std::uint64_t total = 0;
  for (const auto& box : boxes) {
    hits.clear();
    found.clear();
    rtree.query(bgi::intersects(BBox(BPoint(box.min.x, box.min.y), BPoint(box.max.x, box.max.y))),
                std::back_inserter(hits));
    for (const auto& h : hits) found.push_back(h.second);
    std::sort(found.begin(), found.end());
    total += found.size();
  }
  return total;
}
#endif

std::uint64_t brute_range(const std::vector<Double2>& points, std::span<const Box2d> boxes) {
  std::vector<std::uint32_t> found;
  std::uint64_t total = 0;
  for (const auto& box : boxes) {
    found.clear();
    for (std::uint32_t i = 0; i < points.size(); ++i)
      if (box.contains(points[i])) found.push_back(i);
    total += found.size();
  }
  return total;
}

// One round: every bucket size's build and range queries, the ids-only walk, the scan and the
// R-tree, one after the other on the same boxes.
void run_round(Bench& bench, const std::string& name, const std::vector<Double2>& points) {
  const Box2d b = bounds_of(points);
  const double width = b.max.x - b.min.x;
  std::vector<std::uint32_t> found;
  for (const std::uint32_t bucket : {4u, 8u, 16u, 32u, 64u}) {
    kiln::QuadtreeBuildOptions o;
    o.bucket_size = bucket;
    o.threads = 1;
    kiln::FlatQuadtree flat;
    const std::string tag = "quadtree b" + std::to_string(bucket);
    bench.add(name + " build " + tag, 1, [&] {
      flat = kiln::build_quadtree(points, o);
      return flat.nodes.size();
    });
    bench.checks[name + " bytes/point " + tag] = std::uint64_t(flat.stats.bytes_per_point * 10);
    const kiln::QuadtreeView tree(flat.nodes, flat.points, flat.ids, flat.root, points.size());
#ifdef KILN_BENCH_GEO
    std::unique_ptr<RTree> rtree;
    if (bucket == 32)
      bench.add(name + " build boost rtree", 1, [&] {
        rtree = build_rtree(points);
        return rtree->size();
      });
#endif
    const auto centres = boxes_around(points, 1e-4 * width, bench.queries, 9);
    bench.add(name + " knn8 " + tag, centres.size(), [&] {
      std::uint64_t total = 0;
      std::vector<kiln::Neighbor2> near(8);
      for (const auto& c : centres) total += tree.nearest(c.min, near);
      return total;
    });
    for (const double side : {0.001, 0.01, 0.05}) {
      // Fewer of the larger boxes: each returns hundreds to thousands of points.
      const std::size_t count = side < 0.005  ? bench.queries
                                : side < 0.03 ? bench.queries / 4
                                              : bench.queries / 40;
      const auto boxes = boxes_around(points, side * width, std::max<std::size_t>(count, 20), 7);
      const std::string what = name + " range " + std::to_string(side).substr(0, 5) + " ";
      bench.add(what + tag, boxes.size(), [&] {
        std::uint64_t total = 0;
        for (const auto& box : boxes) tree.range(box, found), total += found.size();
        return total;
      });
      if (bucket != 32) continue;
      bench.add(what + "walk only, copies", boxes.size(), [&] {
        std::uint64_t total = 0;
        for (const auto& box : boxes)
          range_walk<false>(tree, points, box, found), total += found.size();
        return total;
      });
      bench.add(what + "walk only, ids-only", boxes.size(), [&] {
        std::uint64_t total = 0;
        for (const auto& box : boxes)
          range_walk<true>(tree, points, box, found), total += found.size();
        return total;
      });
      const std::size_t brute_count = std::max<std::size_t>(20, boxes.size() / 200);
      bench.add(what + "brute force", brute_count,
                [&] { return brute_range(points, std::span(boxes).first(brute_count)); });
#ifdef KILN_BENCH_GEO
      bench.add(what + "boost rtree", boxes.size(), [&] { return rtree_range(*rtree, boxes); });
#endif
    }
  }
}

void print(const Bench& bench) {
  std::printf("| measurement | median | results per query |\n|---|---|---|\n");
  for (const auto& [label, t] : bench.times) {
    const double m = median(t);
    const bool build = label.find(" build ") != std::string::npos;
    std::printf("| %s | %.3f %s | %llu |\n", label.c_str(), build ? m * 1e3 : m * 1e6,
                build ? "ms" : "us/query", (unsigned long long)bench.checks.at(label));
  }
  for (const auto& [label, v] : bench.checks)
    if (label.find("bytes/point") != std::string::npos)
      std::printf("| %s | %.1f | |\n", label.c_str(), double(v) / 10);
}

}  // namespace

int main(int argc, char** argv) {
  Bench bench;
  std::string zip;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::printf(
          "usage: %s [ZIP_POINTS.csv[.zst]] [--rounds=N] [--queries=N]\n"
          "Range queries on the quadtree against Boost.Geometry's R-tree and a scan, on the ZIP\n"
          "points (when given) and 10^6 uniform points; medians of alternating rounds.\n",
          argv[0]);
      return 0;
    }
    if (arg.rfind("--rounds=", 0) == 0)
      bench.rounds = std::stoi(arg.substr(9));
    else if (arg.rfind("--queries=", 0) == 0)
      bench.queries = std::stoul(arg.substr(10));
    else
      zip = arg;
  }
  Box2d world{{-180, -90}, {180, 90}};
  if (!zip.empty()) {
    const auto points = read_zip_points(zip);
    world = bounds_of(points);
    for (int round = 0; round < bench.rounds; ++round) run_round(bench, "zip", points);
  }
  const auto uniform = uniform_points(1000000, world, 42);
  for (int round = 0; round < bench.rounds; ++round) run_round(bench, "uniform", uniform);
  print(bench);
  return 0;
}
