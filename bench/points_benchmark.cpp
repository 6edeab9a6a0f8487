// Point k-d tree throughput against nanoflann (Debian libnanoflann-dev, benchmark only) on the
// same points and queries, single thread: build, kNN (k = 1, 8, 32) and radius searches, leaf
// sizes 10 and 32; and closest-point queries per second on the BVH and the SAH k-d tree.
//
// Usage: kiln_bench_points [--queries=N] [--seed=N] MESH... [benchmark flags]
//   Points are the mesh's vertices (a point cloud's points). Queries: half are vertices moved by
//   up to 1 % of the bounds' diagonal (normal estimation, ICP), half uniform in the bounds.
//   Every benchmark keeps its fastest iteration (least noisy on a small, shared machine); a
//   Markdown table with Kiln ÷ nanoflann ratios is printed at the end.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <nanoflann.hpp>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "bench_args.hpp"
#include "kiln/compiler/build.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/compiler/kdtree_builder.hpp"
#include "kiln/compiler/point_tree_builder.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/kdtree.hpp"
#include "kiln/runtime/point_tree.hpp"

namespace {

using Clock = std::chrono::steady_clock;
using kiln::format::Float3;

// nanoflann's dataset adaptor over the same array Kiln builds from.
struct Cloud {
  const std::vector<Float3>* points;
  std::size_t kdtree_get_point_count() const { return points->size(); }
  float kdtree_get_pt(std::size_t i, std::size_t axis) const {
    const Float3& p = (*points)[i];
    return axis == 0 ? p.x : axis == 1 ? p.y : p.z;
  }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};
using NanoTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, Cloud>,
                                                     Cloud, 3, std::uint32_t>;

struct Case {
  std::string label;
  kiln::Scene scene;
  std::vector<Float3> queries;
  float radius = 0;  // the median 8th-neighbour distance: about 8 points per radius query
  std::map<std::string, double> seconds;  // fastest run per measurement
  std::map<std::string, std::uint64_t> checks;
};

struct Settings {
  std::size_t queries = 100000;
  std::uint32_t seed = 1;
} g_settings;
std::vector<std::unique_ptr<Case>> g_cases;

std::vector<Float3> make_queries(const std::vector<Float3>& points, std::size_t count,
                                 std::uint32_t seed) {
  std::mt19937 rng(seed);
  const kiln::format::Box3f b = kiln::bounds_of(points);
  const float diagonal = std::hypot(b.max.x - b.min.x, b.max.y - b.min.y, b.max.z - b.min.z);
  std::uniform_real_distribution<float> unit(0, 1), jitter(-0.01f * diagonal, 0.01f * diagonal);
  std::uniform_int_distribution<std::size_t> pick(0, points.size() - 1);
  std::vector<Float3> queries(count);
  for (std::size_t i = 0; i < count; ++i) {
    if (i % 2 == 0) {
      const Float3 p = points[pick(rng)];
      queries[i] = {p.x + jitter(rng), p.y + jitter(rng), p.z + jitter(rng)};
    } else {
      queries[i] = {b.min.x + (b.max.x - b.min.x) * unit(rng),
                    b.min.y + (b.max.y - b.min.y) * unit(rng),
                    b.min.z + (b.max.z - b.min.z) * unit(rng)};
    }
  }
  return queries;
}

// Times `body` once per benchmark iteration; the case keeps the fastest.
template <class Body>
void timed(benchmark::State& state, Case& c, const std::string& key, Body body) {
  for (auto _ : state) {
    const auto start = Clock::now();
    body();
    const double s = std::chrono::duration<double>(Clock::now() - start).count();
    state.SetIterationTime(s);
    auto [it, fresh] = c.seconds.emplace(key, s);
    if (!fresh) it->second = std::min(it->second, s);
  }
}

std::string leaf_key(const char* what, std::uint32_t leaf) {
  return std::string(what) + "/leaf" + std::to_string(leaf);
}

// Both trees for one leaf size, built on first use so any --benchmark_filter works.
struct Trees {
  Trees(const std::vector<Float3>& p, std::uint32_t l) : points(&p), leaf(l), cloud{&p} {}
  const std::vector<Float3>* points;
  std::uint32_t leaf;
  Cloud cloud;
  std::optional<kiln::FlatPointTree> kiln_tree;
  std::unique_ptr<NanoTree> nano_tree;

  kiln::PointTreeBuildOptions options() const {
    kiln::PointTreeBuildOptions o;
    o.max_leaf_size = leaf;
    o.threads = 1;
    return o;
  }
  kiln::PointTreeView kiln_view() {
    if (!kiln_tree) kiln_tree.emplace(kiln::build_point_tree(*points, options()));
    const auto& t = *kiln_tree;
    return kiln::PointTreeView(t.nodes, t.points, t.ids, t.bounds);
  }
  const NanoTree& nano() {
    if (!nano_tree)
      nano_tree =
          std::make_unique<NanoTree>(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(leaf));
    return *nano_tree;
  }
};

void register_case(Case* c) {
  const auto& points = c->scene.positions;
  for (const std::uint32_t leaf : {10u, 32u}) {
    auto trees = std::make_shared<Trees>(points, leaf);
    const std::string prefix = c->label + "/leaf" + std::to_string(leaf) + "/";
    benchmark::RegisterBenchmark(
        (prefix + "build/kiln").c_str(),
        [=](benchmark::State& state) {
          const kiln::PointTreeBuildOptions options = trees->options();
          timed(state, *c, leaf_key("build/kiln", leaf),
                [&] { trees->kiln_tree.emplace(kiln::build_point_tree(points, options)); });
        })
        ->UseManualTime()
        ->Iterations(5)
        ->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark((prefix + "build/nanoflann").c_str(),
                                 [=](benchmark::State& state) {
                                   timed(state, *c, leaf_key("build/nanoflann", leaf), [&] {
                                     trees->nano_tree = std::make_unique<NanoTree>(
                                         3, trees->cloud,
                                         nanoflann::KDTreeSingleIndexAdaptorParams(leaf));
                                   });
                                 })
        ->UseManualTime()
        ->Iterations(5)
        ->Unit(benchmark::kMillisecond);

    for (const std::uint32_t k : {1u, 8u, 32u}) {
      const std::string knn = "knn" + std::to_string(k);
      benchmark::RegisterBenchmark(
          (prefix + knn + "/kiln").c_str(),
          [=](benchmark::State& state) {
            const kiln::PointTreeView view = trees->kiln_view();
            std::vector<kiln::Neighbor> found(k);
            double sum = 0;
            timed(state, *c, leaf_key((knn + "/kiln").c_str(), leaf), [&] {
              for (const Float3& q : c->queries) {
                view.nearest(q, found);
                sum += found[k - 1].distance2;
              }
            });
            benchmark::DoNotOptimize(sum);
            if (k == 8 && leaf == 10) {  // the radius for the radius benchmarks
              std::vector<float> eighth;
              for (const Float3& q : c->queries) {
                view.nearest(q, found);
                eighth.push_back(std::sqrt(found[7].distance2));
              }
              std::nth_element(eighth.begin(), eighth.begin() + eighth.size() / 2, eighth.end());
              c->radius = eighth[eighth.size() / 2];
            }
          })
          ->UseManualTime()
          ->Iterations(5)
          ->Unit(benchmark::kMillisecond);
      benchmark::RegisterBenchmark(
          (prefix + knn + "/nanoflann").c_str(),
          [=](benchmark::State& state) {
            const NanoTree& tree = trees->nano();
            std::vector<std::uint32_t> ids(k);
            std::vector<float> d2(k);
            double sum = 0;
            timed(state, *c, leaf_key((knn + "/nanoflann").c_str(), leaf), [&] {
              for (const Float3& q : c->queries) {
                nanoflann::KNNResultSet<float, std::uint32_t> result(k);
                result.init(ids.data(), d2.data());
                const float p[3] = {q.x, q.y, q.z};
                tree.findNeighbors(result, p, nanoflann::SearchParams());
                sum += d2[k - 1];
              }
            });
            benchmark::DoNotOptimize(sum);
            // Same answers? The k-th distance must be equal (ids may differ on exact ties).
            const kiln::PointTreeView view = trees->kiln_view();
            std::vector<kiln::Neighbor> found(k);
            std::uint64_t differ = 0;
            for (const Float3& q : c->queries) {
              nanoflann::KNNResultSet<float, std::uint32_t> result(k);
              result.init(ids.data(), d2.data());
              const float p[3] = {q.x, q.y, q.z};
              tree.findNeighbors(result, p, nanoflann::SearchParams());
              view.nearest(q, found);
              differ += found[k - 1].distance2 != d2[k - 1];
            }
            c->checks[leaf_key((knn + " differ").c_str(), leaf)] = differ;
          })
          ->UseManualTime()
          ->Iterations(5)
          ->Unit(benchmark::kMillisecond);
    }

    benchmark::RegisterBenchmark((prefix + "radius/kiln").c_str(),
                                 [=](benchmark::State& state) {
                                   const kiln::PointTreeView view = trees->kiln_view();
                                   std::vector<kiln::Neighbor> found;
                                   std::uint64_t total = 0;
                                   timed(state, *c, leaf_key("radius/kiln", leaf), [&] {
                                     total = 0;
                                     for (const Float3& q : c->queries) {
                                       view.within_radius(q, c->radius, found);
                                       total += found.size();
                                     }
                                   });
                                   c->checks[leaf_key("radius found/kiln", leaf)] = total;
                                 })
        ->UseManualTime()
        ->Iterations(5)
        ->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark((prefix + "radius/nanoflann").c_str(),
                                 [=](benchmark::State& state) {
                                   const NanoTree& tree = trees->nano();
                                   std::vector<std::pair<std::uint32_t, float>> found;
                                   std::uint64_t total = 0;
                                   timed(state, *c, leaf_key("radius/nanoflann", leaf), [&] {
                                     total = 0;
                                     for (const Float3& q : c->queries) {
                                       const float p[3] = {q.x, q.y, q.z};
                                       found.clear();
                                       total += tree.radiusSearch(p, c->radius * c->radius, found,
                                                                  nanoflann::SearchParams());
                                     }
                                   });
                                   c->checks[leaf_key("radius found/nanoflann", leaf)] = total;
                                 })
        ->UseManualTime()
        ->Iterations(5)
        ->Unit(benchmark::kMillisecond);
  }

  // Closest point on the surface, on the two triangle structures (a tenth of the queries).
  if (c->scene.triangles.empty()) return;
  const std::span<const Float3> few(c->queries.data(), c->queries.size() / 10);
  benchmark::RegisterBenchmark((c->label + "/closest/bvh").c_str(),
                               [=](benchmark::State& state) {
                                 const kiln::FlatBvh bvh = kiln::build_bvh(c->scene, {});
                                 const kiln::BvhView view(bvh.nodes, bvh.triangles, bvh.prim_ids);
                                 double sum = 0;
                                 timed(state, *c, "closest/bvh", [&] {
                                   for (const Float3& q : few)
                                     sum += kiln::closest_point(view, q).distance;
                                 });
                                 benchmark::DoNotOptimize(sum);
                               })
      ->UseManualTime()
      ->Iterations(3)
      ->Unit(benchmark::kMillisecond);
  benchmark::RegisterBenchmark((c->label + "/closest/kdtree").c_str(),
                               [=](benchmark::State& state) {
                                 const kiln::FlatKdTree kd = kiln::build_kdtree(c->scene, {});
                                 const kiln::KdTreeView view(kd.nodes, kd.prim_ids, kd.triangles,
                                                             kd.bounds);
                                 double sum = 0;
                                 timed(state, *c, "closest/kdtree", [&] {
                                   for (const Float3& q : few)
                                     sum += kiln::closest_point(view, q).distance;
                                 });
                                 benchmark::DoNotOptimize(sum);
                               })
      ->UseManualTime()
      ->Iterations(3)
      ->Unit(benchmark::kMillisecond);
}

void print_report() {
  std::printf("\n| points | leaf | build Kiln ms | build nanoflann ms |");
  for (const char* q : {"kNN 1", "kNN 8", "kNN 32", "radius"})
    std::printf(" %s Kiln Mq/s | %s nanoflann Mq/s | %s ratio |", q, q, q);
  std::printf("\n|---|---:|---:|---:|");
  for (int i = 0; i < 4; ++i) std::printf("---:|---:|---:|");
  std::printf("\n");
  for (const auto& c : g_cases) {
    for (const std::uint32_t leaf : {10u, 32u}) {
      auto at = [&](const std::string& key) {
        const auto it = c->seconds.find(leaf_key(key.c_str(), leaf));
        return it == c->seconds.end() ? NAN : it->second;
      };
      std::printf("| %s (%zu) | %u | %.2f | %.2f |", c->label.c_str(), c->scene.positions.size(),
                  leaf, at("build/kiln") * 1e3, at("build/nanoflann") * 1e3);
      for (const char* q : {"knn1", "knn8", "knn32", "radius"}) {
        const double mine = double(c->queries.size()) / at(std::string(q) + "/kiln") * 1e-6;
        const double theirs = double(c->queries.size()) / at(std::string(q) + "/nanoflann") * 1e-6;
        std::printf(" %.3f | %.3f | %.2f× |", mine, theirs, mine / theirs);
      }
      std::printf("\n");
    }
  }
  std::printf("\nChecks (same answers):\n");
  for (const auto& c : g_cases) {
    std::printf("  %s: %zu queries, radius %g\n", c->label.c_str(), c->queries.size(),
                double(c->radius));
    for (const auto& [key, value] : c->checks)
      std::printf("    %s: %llu\n", key.c_str(), (unsigned long long)value);
    for (const char* s : {"closest/bvh", "closest/kdtree"})
      if (c->seconds.count(s))
        std::printf("    %s: %.3f Mq/s\n", s,
                    double(c->queries.size() / 10) / c->seconds.at(s) * 1e-6);
  }
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  std::vector<std::string> meshes;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    try {
      if (kiln::bench::parse_number_option(arg, "queries", g_settings.queries) ||
          kiln::bench::parse_number_option(arg, "seed", g_settings.seed))
        continue;
    } catch (const std::exception&) {
      std::fprintf(stderr, "bad number in '%s'\n", arg.c_str());
      return 2;
    }
    if (arg.starts_with("--")) {
      std::fprintf(stderr, "unknown option '%s'\n", arg.c_str());
      return 2;
    }
    meshes.push_back(arg);
  }
  if (meshes.empty() || g_settings.queries < 10) {
    std::fprintf(stderr, "usage: kiln_bench_points [--queries=N] [--seed=N] MESH...\n");
    return 2;
  }
  for (const auto& path : meshes) {
    auto c = std::make_unique<Case>();
    c->label = path.substr(path.find_last_of('/') + 1);
    try {
      c->scene = kiln::import_scene({path}, 0);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s\n", e.what());
      return 1;
    }
    c->queries = make_queries(c->scene.positions, g_settings.queries, g_settings.seed);
    g_cases.push_back(std::move(c));
  }
  for (const auto& c : g_cases) register_case(c.get());
  benchmark::RunSpecifiedBenchmarks();
  print_report();
  benchmark::Shutdown();
  return 0;
}
