// ESVO with and without contours beside the voxel DAG on the same grid: build time, bytes per
// leaf by component, ray casts per second (one thread and all), and the geometric error of the
// hits against the mesh (distance to the closest triangle; hit/miss disagreement with a BVH).
//
// Usage: kiln_bench_esvo [--resolutions=1024,2048] [--rays=N] [--error-rays=N] MESH...
//   MESH as kiln_bench_bvh takes it: a file, or LABEL=@DIR/PATTERN for many files as one scene.
//   Builds run once (they take seconds); casts keep the fastest of 3. A Markdown table is
//   printed at the end.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "bench_args.hpp"
#include "bench_timing.hpp"
#include "kiln/compiler/build.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/compiler/esvo_builder.hpp"
#include "kiln/compiler/voxel_dag_builder.hpp"
#include "kiln/compiler/voxelizer.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/esvo.hpp"
#include "kiln/runtime/ray_structure.hpp"
#include "kiln/runtime/voxel_dag.hpp"
#include "kiln/tools/ray_generator.hpp"

namespace {

struct Settings {
  std::vector<std::uint32_t> resolutions{1024, 2048};
  std::size_t rays = 200000;
  std::size_t error_rays = 20000;
} g_settings;

struct EsvoRow {
  double build_s = NAN, cast_1t = NAN, cast_all = NAN;
  kiln::FlatEsvo stats;  // counts and byte totals only: the arrays stay in Case::built
  double bound = NAN, mean_error = NAN, max_error = NAN, disagreement = NAN;
};

struct DagRow {
  std::uint64_t voxels = 0, bytes = 0;
  double cast_1t = NAN;
};

struct Case {
  std::string label;
  kiln::Scene scene;
  kiln::FlatBvh bvh;
  std::vector<kiln::Ray> rays;
  std::vector<bool> mesh_hit;  // per error ray
  std::map<std::uint32_t, DagRow> dag;
  std::map<std::pair<std::uint32_t, bool>, EsvoRow> esvo;
  std::map<std::pair<std::uint32_t, bool>, std::shared_ptr<kiln::FlatEsvo>> built;
  kiln::BvhView bvh_view() const { return kiln::BvhView(bvh.nodes, bvh.triangles, bvh.prim_ids); }
};
std::vector<std::unique_ptr<Case>> g_cases;

kiln::EsvoView view_of(const kiln::FlatEsvo& e) {
  return kiln::EsvoView(e.words, e.pages, e.blocks, e.normals, e.colors, kiln::frame_of(e.grid));
}

// The figures without the arrays: copying the whole FlatEsvo would briefly double the memory.
kiln::FlatEsvo stats_of(const kiln::FlatEsvo& e) {
  kiln::FlatEsvo s;
  s.grid = e.grid;
  s.levels = e.levels;
  s.level_stats = e.level_stats;
  s.descriptor_count = e.descriptor_count, s.voxel_count = e.voxel_count;
  s.leaf_count = e.leaf_count, s.contour_count = e.contour_count;
  s.far_pointer_count = e.far_pointer_count, s.max_depth = e.max_depth;
  s.hierarchy_bytes = e.hierarchy_bytes, s.contour_bytes = e.contour_bytes;
  s.attachment_bytes = e.attachment_bytes;
  return s;
}

// Distance of every hit to the mesh, in finest voxels, and hit/miss disagreement with the mesh,
// over the first error rays of a cast's own hits (closest_point costs far more than a cast).
void measure_error(const Case& c, std::span<const kiln::VoxelHit> traced, double voxel_size,
                   EsvoRow& row) {
  const kiln::BvhView bvh = c.bvh_view();
  const std::size_t n = c.mesh_hit.size();
  std::size_t hits = 0, disagree = 0;
  double total = 0, worst = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const kiln::Ray& ray = c.rays[i];
    const kiln::VoxelHit& h = traced[i];
    disagree += h.hit() != c.mesh_hit[i];
    if (!h.hit()) continue;
    ++hits;
    const kiln::format::Float3 p{ray.org.x + h.t * ray.dir.x, ray.org.y + h.t * ray.dir.y,
                                 ray.org.z + h.t * ray.dir.z};
    const double d = kiln::closest_point(bvh, p).distance / voxel_size;
    total += d, worst = std::max(worst, d);
  }
  row.mean_error = hits ? total / double(hits) : NAN;
  row.max_error = hits ? worst : NAN;
  row.disagreement = n ? 100.0 * double(disagree) / double(n) : NAN;
}

void register_case(Case* c) {
  for (const std::uint32_t n : g_settings.resolutions) {
    const std::string prefix = c->label + "/" + std::to_string(n) + "/";
    benchmark::RegisterBenchmark(
        (prefix + "dag").c_str(),
        [=](benchmark::State& state) {
          DagRow& row = c->dag[n];
          kiln::Voxels voxels = kiln::voxelize_surface(c->scene, {n, false, 0});
          const kiln::FlatVoxelDag dag = kiln::build_voxel_dag(voxels.codes, n);
          row.voxels = voxels.codes.size();
          row.bytes = dag.dag_bytes;
          std::vector<std::uint64_t>().swap(voxels.codes);  // the casts need only the DAG
          const auto firsts = kiln::level_first_words(dag);
          const kiln::VoxelDagView view(dag.words, kiln::frame_of(voxels.grid), firsts,
                                        dag.leaf_first_word, {}, {});
          std::vector<kiln::VoxelHit> hits(c->rays.size());
          double best = NAN;
          kiln::bench::timed(state, best, [&] { kiln::trace_rays(view, c->rays, hits, false, 1); });
          row.cast_1t = double(c->rays.size()) / best * 1e-6;
        })
        ->UseManualTime()
        ->Iterations(3)
        ->Unit(benchmark::kMillisecond);
    for (const bool contours : {true, false}) {
      const auto key = std::make_pair(n, contours);
      const std::string name = prefix + (contours ? "esvo" : "cubes");
      benchmark::RegisterBenchmark(
          (name + "/build").c_str(),
          [=](benchmark::State& state) {
            EsvoRow& row = c->esvo[key];
            kiln::EsvoBuildOptions options;
            options.resolution = n;
            options.contours = contours;
            row.bound = kiln::esvo_error_bound(options);
            // Whatever an earlier variant left (its casts filtered out) is no longer needed.
            c->built.clear();
            kiln::bench::timed(state, row.build_s, [&] {
              c->built[key].reset();
              c->built[key] = std::make_shared<kiln::FlatEsvo>(kiln::build_esvo(c->scene, options));
            });
            row.stats = stats_of(*c->built[key]);
          })
          ->UseManualTime()
          ->Iterations(1)
          ->Unit(benchmark::kMillisecond);
      for (const unsigned threads : {1u, 0u}) {
        benchmark::RegisterBenchmark(
            (name + (threads == 1 ? "/cast1T" : "/castAll")).c_str(),
            [=](benchmark::State& state) {
              EsvoRow& row = c->esvo[key];
              if (!c->built[key]) {
                state.SkipWithError("run the build benchmark first");
                return;
              }
              const kiln::FlatEsvo& flat = *c->built[key];
              const kiln::EsvoView view = view_of(flat);
              std::vector<kiln::VoxelHit> hits(c->rays.size());
              double best = NAN;
              kiln::bench::timed(state, best,
                                 [&] { kiln::trace_rays(view, c->rays, hits, false, threads); });
              (threads == 1 ? row.cast_1t : row.cast_all) = double(c->rays.size()) / best * 1e-6;
              if (threads != 0) return;
              measure_error(*c, hits, flat.grid.voxel_size, row);
              c->built.erase(key);  // the last cast of this variant
            })
            ->UseManualTime()
            ->Iterations(3)
            ->Unit(benchmark::kMillisecond);
      }
    }
  }
}

void print_report() {
  // The per-component columns are bytes per leaf too, so they add up to the total.
  std::printf(
      "\n| mesh | resolution | contours | build s | leaves | max depth | bytes/leaf total | "
      "hierarchy | contours | attachments | far ptrs | total MB | cast 1T Mrays/s | "
      "cast %uT Mrays/s | mean err vox | max err vox | bound vox | hit/miss disagreement %% | "
      "DAG MB | DAG bits/voxel | DAG cast 1T Mrays/s |\n",
      std::max(1u, std::thread::hardware_concurrency()));
  std::printf(
      "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---"
      ":|---:|---:|\n");
  for (const auto& c : g_cases)
    for (const auto& [key, r] : c->esvo) {
      const auto& s = r.stats;
      const double leaves = double(std::max<std::uint64_t>(1, s.leaf_count));
      const double total = double(s.hierarchy_bytes + s.contour_bytes + s.attachment_bytes);
      const DagRow& dag = c->dag[key.first];
      std::printf(
          "| %s | %u^3 | %s | %.2f | %llu | %u | %.2f | %.2f | %.2f | %.2f | %llu | %.1f | %.2f | "
          "%.2f | %.3f | %.2f | %.2f | %.2f | %.2f | %.3f | %.2f |\n",
          c->label.c_str(), key.first, key.second ? "yes" : "no", r.build_s,
          (unsigned long long)s.leaf_count, s.max_depth, total / leaves,
          double(s.hierarchy_bytes) / leaves, double(s.contour_bytes) / leaves,
          double(s.attachment_bytes) / leaves, (unsigned long long)s.far_pointer_count, total / 1e6,
          r.cast_1t, r.cast_all, r.mean_error, r.max_error, r.bound, r.disagreement,
          double(dag.bytes) / 1e6,
          double(dag.bytes) * 8 / double(std::max<std::uint64_t>(1, dag.voxels)), dag.cast_1t);
    }
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  std::vector<std::string> specs;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    try {
      if (kiln::bench::parse_list_option(arg, "resolutions", g_settings.resolutions) ||
          kiln::bench::parse_number_option(arg, "rays", g_settings.rays) ||
          kiln::bench::parse_number_option(arg, "error-rays", g_settings.error_rays))
        continue;
    } catch (const std::exception&) {
      std::fprintf(stderr, "bad number in '%s'\n", arg.c_str());
      return 2;
    }
    if (arg.starts_with("--")) {
      std::fprintf(stderr, "unknown option '%s'\n", arg.c_str());
      return 2;
    }
    specs.push_back(arg);
  }
  if (specs.empty()) {
    std::fprintf(stderr,
                 "usage: kiln_bench_esvo [--resolutions=1024,2048] [--rays=N] [--error-rays=N] "
                 "MESH...\n");
    return 2;
  }
  for (const auto& spec : specs) {
    auto c = std::make_unique<Case>();
    try {
      const auto mesh = kiln::bench::parse_mesh_spec(spec);
      if (!mesh) return 1;
      c->label = mesh->label;
      c->scene = kiln::import_scene(mesh->files, 0);
      c->bvh = kiln::build_bvh(c->scene, {});
      const kiln::BvhView bvh = c->bvh_view();
      c->rays = kiln::generate_rays(
          {bvh, c->scene.positions, c->scene.triangles, c->scene.bounds.min, c->scene.bounds.max},
          kiln::RayKind::kPrimary, g_settings.rays, 1, 0);
      for (std::size_t i = 0; i < std::min(c->rays.size(), g_settings.error_rays); ++i)
        c->mesh_hit.push_back(bvh.intersect(c->rays[i]).prim != kiln::kNoHit);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s\n", e.what());
      return 1;
    }
    g_cases.push_back(std::move(c));
  }
  for (const auto& c : g_cases) register_case(c.get());
  benchmark::RunSpecifiedBenchmarks();
  print_report();
  benchmark::Shutdown();
  return 0;
}
