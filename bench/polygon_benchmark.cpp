// Point in polygon: Kiln's polygon index against GEOS 3.11 (prepared polygons found through an
// STRtree, GEOSPreparedContains) and Boost.Geometry (an R-tree of feature boxes, then within),
// on the ZIP points and on uniform random points in a layer's bounds. Every engine answers the
// lowest feature index containing each point. Runs alternate engine by engine, `--repeats`
// times; medians are printed. Before timing queries each engine answers every point once, so
// GEOS's lazily built per-polygon indexes exist (its build time does not include them). Benchmark
// only (-DKILN_BENCH_GEO=ON): the runtime never sees GEOS or Boost.
//
//   kiln_bench_polygons [--geo-dir ../shared/data/geo] [--repeats 5] [--random 1000000]
//                       [--max-edges 8] [--max-depth 16] [--only-kiln] [--skip-boost] [--sweep]
//                       [--layer counties|countries]
#include <sys/resource.h>

#include <geos_c.h>

#include <algorithm>
#include <atomic>
#include <boost/geometry.hpp>
#include <boost/geometry/index/rtree.hpp>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <functional>
#include <random>
#include <span>
#include <stdexcept>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "kiln/compiler/csv_reader.hpp"
#include "kiln/compiler/geo_import.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/compiler/polygon_index_builder.hpp"
#include "kiln/runtime/parallel.hpp"
#include "kiln/runtime/polygon_index.hpp"

namespace {

using kiln::PolygonLayer;
using kiln::format::Double2;
namespace bg = boost::geometry;
namespace bgi = boost::geometry::index;

constexpr std::uint32_t kNone = 0xFFFFFFFFu;

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// User + system CPU seconds of this process so far: on a shared machine the single-threaded
// rates are taken per CPU second (the waiting main thread uses none), which time slicing by
// other jobs does not inflate.
double cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

std::string text_of(const std::string& path) {
  const kiln::InputBytes in = kiln::read_input_bytes(path);
  return {reinterpret_cast<const char*>(in.bytes.data()), in.bytes.size()};
}

// Kiln's GeoJSON reader; broken features (the shared states file has one) are dropped.
PolygonLayer load_layer(const std::string& path) {
  kiln::GeoImportOptions options;
  options.skip_invalid = true;
  return *kiln::import_geo_file(path, options).polygons;
}

std::vector<Double2> zip_points(const std::string& path) {
  const std::string text = text_of(path);
  kiln::CsvReader reader(path, text);
  std::vector<std::string_view> fields;
  reader.next(fields);
  const auto lat = *kiln::csv_column(fields, "latitude"),
             lon = *kiln::csv_column(fields, "longitude");
  std::vector<Double2> points;
  while (reader.next(fields))
    points.push_back({std::stod(std::string(fields[lon])), std::stod(std::string(fields[lat]))});
  return points;
}

// One engine: build() then locate(i) for the lowest feature holding point i, on any thread
// (`thread` picks per-thread state).
struct Engine {
  std::string name;
  std::function<void()> build;
  std::function<std::uint32_t(const Double2&, unsigned thread)> locate;
  std::function<std::size_t()> bytes;  // 0: not known
  // A batch call (Kiln's locate_many), timed apart from the per-point calls; empty: none.
  std::function<void(std::span<const Double2>, std::span<std::uint32_t>)> locate_many;
  std::function<std::string()> info;  // a line about the last build; empty: none
};

// Answers every point on `threads` threads (batches of 4096, each thread its own slot).
std::vector<std::uint32_t> run(const Engine& e, const std::vector<Double2>& points,
                               unsigned threads) {
  std::vector<std::uint32_t> out(points.size());
  const std::size_t batch = 4096, batches = (points.size() + batch - 1) / batch;
  std::atomic<std::size_t> next{0};
  std::vector<std::thread> pool;
  for (unsigned t = 0; t < threads; ++t)
    pool.emplace_back([&, t] {
      for (std::size_t b = next++; b < batches; b = next++)
        for (std::size_t i = b * batch; i < std::min(points.size(), (b + 1) * batch); ++i)
          out[i] = e.locate(points[i], t);
    });
  for (auto& thread : pool) thread.join();
  return out;
}

// The same on one thread through the engine's batch call, batches of 4096 as above.
std::vector<std::uint32_t> run_many(const Engine& e, const std::vector<Double2>& points) {
  std::vector<std::uint32_t> out(points.size());
  std::thread([&] {
    for (std::size_t i = 0; i < points.size(); i += 4096) {
      const std::size_t n = std::min<std::size_t>(4096, points.size() - i);
      e.locate_many(std::span(points).subspan(i, n), std::span(out).subspan(i, n));
    }
  }).join();
  return out;
}

// ---- Kiln ----
Engine kiln_engine(const PolygonLayer& layer, kiln::PolygonIndexBuildOptions options) {
  auto index = std::make_shared<kiln::FlatPolygonIndex>();
  auto view = std::make_shared<std::unique_ptr<kiln::PolygonIndexView>>();
  auto open_ms = std::make_shared<double>();
  return {"kiln",
          [&layer, index, view, options, open_ms] {
            *index = kiln::build_polygon_index(kiln::view_of(layer), options);
            const auto start = std::chrono::steady_clock::now();
            *view = std::make_unique<kiln::PolygonIndexView>(kiln::PolygonIndexParts{
                kiln::view_of(layer), index->bounds, index->nodes, index->entries, index->edges});
            *open_ms = 1e3 * seconds_since(start);
          },
          [view](const Double2& p, unsigned) { return (*view)->locate(p); },
          [index] {
            return index->nodes.size() * 8 + index->entries.size() * 12 + index->edges.size() * 8;
          },
          [view](std::span<const Double2> p, std::span<std::uint32_t> out) {
            (*view)->locate_many(p, out);
          },
          [view, open_ms] {
            // What the view derives at open (table, branches, leaf records), rebuilt here to
            // count it.
            const auto g = kiln::make_polygon_index_top_grid((*view)->parts());
            const std::size_t cells = std::size_t(1) << 2 * g->level;
            const std::size_t table = cells * 4 + g->clear.size() * 8 +
                                      (g->xs.size() + g->ys.size()) * 8 + g->feature.size() * 4;
            const std::size_t branches = (g->code.size() - cells) * 4;
            const std::size_t records = branches + g->records.size() * 8;
            return "open (validate + derive) " + std::to_string(*open_ms).substr(0, 6) +
                   " ms; derived at open: top table level " + std::to_string(g->level) + ", " +
                   std::to_string(table) + " bytes; branches " + std::to_string(branches) +
                   " + leaf records " + std::to_string(g->records.size() * 8) + " = " +
                   std::to_string(records) + " bytes";
          }};
}

// ---- GEOS ----
struct GeosState {
  std::vector<GEOSContextHandle_t> handles;  // one per thread
  std::vector<GEOSGeometry*> features;
  std::vector<const GEOSPreparedGeometry*> prepared;
  GEOSSTRtree* tree = nullptr;
  std::vector<std::uint32_t> ids;  // tree items point here
  void clear() {
    GEOSContextHandle_t h = handles[0];
    if (tree) GEOSSTRtree_destroy_r(h, tree);
    for (auto* p : prepared) GEOSPreparedGeom_destroy_r(h, p);
    for (auto* g : features) GEOSGeom_destroy_r(h, g);
    tree = nullptr, prepared.clear(), features.clear();
  }
};

GEOSGeometry* geos_ring(GEOSContextHandle_t h, std::span<const Double2> ring) {
  GEOSCoordSequence* s = GEOSCoordSeq_create_r(h, unsigned(ring.size() + 1), 2);
  for (std::size_t i = 0; i <= ring.size(); ++i)
    GEOSCoordSeq_setXY_r(h, s, unsigned(i), ring[i % ring.size()].x, ring[i % ring.size()].y);
  return GEOSGeom_createLinearRing_r(h, s);
}

GEOSGeometry* geos_feature(GEOSContextHandle_t h, const PolygonLayer& l, std::size_t f) {
  std::vector<GEOSGeometry*> polys;
  for (auto q = l.feature_polygons[f]; q < l.feature_polygons[f + 1]; ++q) {
    auto ring = [&](std::uint64_t r) {
      return geos_ring(
          h, std::span(l.vertices)
                 .subspan(l.ring_vertices[r], l.ring_vertices[r + 1] - l.ring_vertices[r]));
    };
    std::vector<GEOSGeometry*> holes;
    for (auto r = l.polygon_rings[q] + 1; r < l.polygon_rings[q + 1]; ++r) holes.push_back(ring(r));
    polys.push_back(GEOSGeom_createPolygon_r(h, ring(l.polygon_rings[q]), holes.data(),
                                             unsigned(holes.size())));
  }
  return GEOSGeom_createCollection_r(h, GEOS_MULTIPOLYGON, polys.data(), unsigned(polys.size()));
}

Engine geos_engine(const PolygonLayer& layer, unsigned threads) {
  auto s = std::make_shared<GeosState>();
  for (unsigned t = 0; t < threads; ++t) s->handles.push_back(GEOS_init_r());
  s->ids.resize(layer.feature_count());
  for (std::size_t f = 0; f < s->ids.size(); ++f) s->ids[f] = std::uint32_t(f);
  return {"geos",
          [&layer, s] {
            s->clear();
            GEOSContextHandle_t h = s->handles[0];
            s->tree = GEOSSTRtree_create_r(h, 10);
            for (std::size_t f = 0; f < layer.feature_count(); ++f) {
              s->features.push_back(geos_feature(h, layer, f));
              s->prepared.push_back(GEOSPrepare_r(h, s->features.back()));
              GEOSSTRtree_insert_r(h, s->tree, s->features.back(), &s->ids[f]);
            }
            // Build the tree now (GEOS builds it on the first query), outside the timed queries.
            GEOSGeometry* p = GEOSGeom_createPointFromXY_r(h, 0, 0);
            GEOSSTRtree_query_r(
                h, s->tree, p, [](void*, void*) {}, nullptr);
            GEOSGeom_destroy_r(h, p);
          },
          [s](const Double2& q, unsigned t) {
            GEOSContextHandle_t h = s->handles[t];
            GEOSGeometry* p = GEOSGeom_createPointFromXY_r(h, q.x, q.y);
            std::vector<std::uint32_t> candidates;
            GEOSSTRtree_query_r(
                h, s->tree, p,
                [](void* item, void* out) {
                  static_cast<std::vector<std::uint32_t>*>(out)->push_back(
                      *static_cast<std::uint32_t*>(item));
                },
                &candidates);
            std::sort(candidates.begin(), candidates.end());
            std::uint32_t found = kNone;
            for (const auto f : candidates)
              if (GEOSPreparedContains_r(h, s->prepared[f], p) == 1) {
                found = f;
                break;
              }
            GEOSGeom_destroy_r(h, p);
            return found;
          },
          [] { return std::size_t(0); },
          {},
          {}};
}

// ---- Boost.Geometry ----
using BPoint = bg::model::d2::point_xy<double>;
using BPolygon = bg::model::polygon<BPoint>;  // clockwise, closed: rings corrected at build
using BMulti = bg::model::multi_polygon<BPolygon>;
using BBox = bg::model::box<BPoint>;
using BItem = std::pair<BBox, std::uint32_t>;

struct BoostState {
  std::vector<BMulti> features;
  bgi::rtree<BItem, bgi::rstar<16>> tree;
};

Engine boost_engine(const PolygonLayer& layer) {
  auto s = std::make_shared<BoostState>();
  return {"boost",
          [&layer, s] {
            s->features.assign(layer.feature_count(), {});
            std::vector<BItem> items;
            for (std::size_t f = 0; f < layer.feature_count(); ++f) {
              BMulti& m = s->features[f];
              for (auto q = layer.feature_polygons[f]; q < layer.feature_polygons[f + 1]; ++q) {
                BPolygon poly;
                for (auto r = layer.polygon_rings[q]; r < layer.polygon_rings[q + 1]; ++r) {
                  auto& ring =
                      r == layer.polygon_rings[q] ? poly.outer() : poly.inners().emplace_back();
                  for (auto i = layer.ring_vertices[r]; i < layer.ring_vertices[r + 1]; ++i)
                    ring.push_back({layer.vertices[i].x, layer.vertices[i].y});
                  ring.push_back(ring.front());
                }
                bg::correct(poly);
                m.push_back(std::move(poly));
              }
              items.push_back({bg::return_envelope<BBox>(m), std::uint32_t(f)});
            }
            s->tree = bgi::rtree<BItem, bgi::rstar<16>>(items);  // packing (STR-like) build
          },
          [s](const Double2& q, unsigned) {
            const BPoint p(q.x, q.y);
            std::vector<BItem> hits;
            s->tree.query(bgi::intersects(p), std::back_inserter(hits));
            std::sort(hits.begin(), hits.end(),
                      [](auto& a, auto& b) { return a.second < b.second; });
            for (const auto& [box, f] : hits)
              if (bg::within(p, s->features[f])) return f;
            return kNone;
          },
          [] { return std::size_t(0); },
          {},
          {}};
}

// Deterministic cost of each max-edges setting (edges tested and cells visited per query, from
// locate_counting), beside its size and build time: how the default was chosen.
void sweep(const std::string& dir, const std::vector<Double2>& zips) {
  for (const char* file : {"us-counties-10m.geojson.zst", "countries-land-10km.geojson.zst"}) {
    const PolygonLayer layer = load_layer(dir + file);
    std::printf("\n%s: max-edges sweep (max-depth 16)\n%9s %10s %12s %14s %14s\n", file,
                "max-edges", "build ms", "index bytes", "zip edges/q", "zip cells/q");
    for (const std::uint32_t max_edges : {4u, 8u, 16u, 32u, 64u, 128u}) {
      std::vector<double> build;
      kiln::FlatPolygonIndex index;
      for (int r = 0; r < 3; ++r) {
        const auto start = std::chrono::steady_clock::now();
        index = kiln::build_polygon_index(kiln::view_of(layer), {max_edges, 16, 2});
        build.push_back(seconds_since(start));
      }
      const kiln::PolygonIndexView view(
          {kiln::view_of(layer), index.bounds, index.nodes, index.entries, index.edges});
      kiln::Cost cost;
      for (const Double2& p : zips) view.locate_counting(p, cost);
      const std::size_t bytes =
          index.nodes.size() * 8 + index.entries.size() * 12 + index.edges.size() * 8;
      std::printf("%9u %10.1f %12zu %14.2f %14.2f\n", max_edges, 1e3 * median(build), bytes,
                  double(cost.tests) / double(zips.size()),
                  double(cost.nodes) / double(zips.size()));
    }
  }
}

struct Args {
  std::string dir = "../shared/data/geo/";
  int repeats = 5;
  std::size_t random = 1000000;
  kiln::PolygonIndexBuildOptions options{8, 16, 2};
  bool only_kiln = false;
  bool sweep = false;
  bool skip_boost = false;
  std::string layer;  // "counties" or "countries": only that layer (empty: both)
};

void bench_layer(const Args& a, const char* file, const std::vector<Double2>& zips) {
  const PolygonLayer layer = load_layer(a.dir + file);
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> x(layer.bounds.min.x, layer.bounds.max.x),
      y(layer.bounds.min.y, layer.bounds.max.y);
  std::vector<Double2> random(a.random);
  for (auto& p : random) p = {x(rng), y(rng)};
  std::vector<Engine> engines{kiln_engine(layer, a.options)};
  if (!a.only_kiln) engines.push_back(geos_engine(layer, 2));
  if (!a.only_kiln && !a.skip_boost) engines.push_back(boost_engine(layer));
  struct Times {
    std::vector<double> build, zip1, zip2, rnd1, rnd2, zipb, rndb;
  };
  std::vector<Times> times(engines.size());
  std::vector<std::vector<std::uint32_t>> answers(engines.size()), zip_answers(engines.size());
  for (int r = 0; r < a.repeats; ++r)
    for (std::size_t e = 0; e < engines.size(); ++e) {  // alternate engines within each repeat
      auto start = std::chrono::steady_clock::now();
      engines[e].build();
      times[e].build.push_back(seconds_since(start));
      // One untimed pass first: GEOS prepares each polygon's own index lazily, on its first
      // contains (the build time above leaves that out; Kiln and Boost have nothing lazy).
      run(engines[e], zips, 1);
      run(engines[e], random, 1);
      for (auto [set, t1, t2, tb] :
           {std::tuple{&zips, &times[e].zip1, &times[e].zip2, &times[e].zipb},
            std::tuple{static_cast<const std::vector<Double2>*>(&random), &times[e].rnd1,
                       &times[e].rnd2, &times[e].rndb}}) {
        // Small sets (the ZIP points: a few ms) run several passes per timing, so each timing
        // covers at least 500,000 queries and a scheduler hiccup weighs less.
        const std::size_t passes = std::max<std::size_t>(1, 500000 / set->size());
        const double cpu = cpu_seconds();
        for (std::size_t k = 0; k < passes; ++k) answers[e] = run(engines[e], *set, 1);
        t1->push_back(double(passes * set->size()) / (cpu_seconds() - cpu));
        if (set == &zips) zip_answers[e] = answers[e];
        if (engines[e].locate_many) {
          const double cpu_many = cpu_seconds();
          std::vector<std::uint32_t> many;
          for (std::size_t k = 0; k < passes; ++k) many = run_many(engines[e], *set);
          tb->push_back(double(passes * set->size()) / (cpu_seconds() - cpu_many));
          if (many != answers[e]) throw std::runtime_error("locate_many differs from locate");
        }
        start = std::chrono::steady_clock::now();
        for (std::size_t k = 0; k < passes; ++k) run(engines[e], *set, 2);
        t2->push_back(double(passes * set->size()) / seconds_since(start));
      }
    }
  std::printf("\n%s: %zu features, %zu polygons, %zu vertices; %zu ZIP points, %zu random points\n",
              file, layer.feature_count(), layer.polygon_count(), layer.vertices.size(),
              zips.size(), random.size());
  std::printf("%-6s %10s %12s %12s %12s %12s %12s\n", "engine", "build ms", "index bytes",
              "zip q/cpu-s 1T", "zip q/s 2T", "rand q/cpu-s 1T", "rand q/s 2T");
  for (std::size_t e = 0; e < engines.size(); ++e)
    if (engines[e].info)
      std::printf("%-6s %s\n", engines[e].name.c_str(), engines[e].info().c_str());
  for (std::size_t e = 0; e < engines.size(); ++e)
    if (!times[e].zipb.empty())
      std::printf("%-6s batch calls (locate_many), 1T: zip %.3g q/cpu-s, rand %.3g q/cpu-s\n",
                  engines[e].name.c_str(), median(times[e].zipb), median(times[e].rndb));
  for (std::size_t e = 0; e < engines.size(); ++e) {
    const std::size_t bytes = engines[e].bytes();
    std::printf("%-6s %10.1f %12s %12.3g %12.3g %12.3g %12.3g\n", engines[e].name.c_str(),
                1e3 * median(times[e].build), bytes ? std::to_string(bytes).c_str() : "n/a",
                median(times[e].zip1), median(times[e].zip2), median(times[e].rnd1),
                median(times[e].rnd2));
  }
  // Agreement on the random points (the last set answered): Kiln counts a boundary point in one
  // polygon, GEOS and Boost in none, so only points exactly on a border may differ.
  for (std::size_t e = 1; e < engines.size(); ++e) {
    std::size_t differ = 0;
    for (std::size_t i = 0; i < random.size(); ++i)
      if (answers[e][i] != answers[0][i] && ++differ <= 5)
        std::printf("  (%.17g, %.17g): kiln %d, %s %d\n", random[i].x, random[i].y,
                    int(answers[0][i]), engines[e].name.c_str(), int(answers[e][i]));
    std::printf("kiln vs %s: %zu of %zu random points differ\n", engines[e].name.c_str(), differ,
                random.size());
    // The ZIP points (MANIFEST.md: on the counties, the same county wherever GEOS finds one).
    differ = 0;
    for (std::size_t i = 0; i < zips.size(); ++i) differ += zip_answers[e][i] != zip_answers[0][i];
    const auto none = std::count(zip_answers[0].begin(), zip_answers[0].end(), kNone);
    std::printf("kiln vs %s: %zu of %zu ZIP points differ (kiln: %zu in none)\n",
                engines[e].name.c_str(), differ, zips.size(), std::size_t(none));
  }
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&] { return i + 1 < argc ? std::string(argv[++i]) : std::string(); };
    if (arg == "--geo-dir")
      a.dir = value() + "/";
    else if (arg == "--repeats")
      a.repeats = std::max(1, std::stoi(value()));
    else if (arg == "--random")
      a.random = std::stoul(value());
    else if (arg == "--max-edges")
      a.options.max_edges = std::stoul(value());
    else if (arg == "--max-depth")
      a.options.max_depth = std::stoul(value());
    else if (arg == "--only-kiln")
      a.only_kiln = true;
    else if (arg == "--sweep")
      a.sweep = true;
    else if (arg == "--skip-boost")
      a.skip_boost = true;
    else if (arg == "--layer")
      a.layer = value();
    else {
      std::fprintf(stderr, "kiln_bench_polygons: unknown argument '%s'\n", arg.c_str());
      return 2;
    }
  }
  try {
    const auto zips = zip_points(a.dir + "zipcodes.csv.zst");
    std::printf(
        "kiln_bench_polygons: %d repeats (medians), max-edges %u, max-depth %u, build on 2 "
        "threads\n",
        a.repeats, a.options.max_edges, a.options.max_depth);
    if (a.sweep) {
      sweep(a.dir, zips);
      return 0;
    }
    if (a.layer != "countries") bench_layer(a, "us-counties-10m.geojson.zst", zips);
    if (a.layer != "counties") bench_layer(a, "countries-land-10km.geojson.zst", zips);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "kiln_bench_polygons: %s\n", e.what());
    return 1;
  }
  return 0;
}
