// Voxel DAG: voxelization and DAG construction time, sizes per resolution, and ray casts per
// second (single thread and all threads) on primary rays.
//
// Usage: kiln_bench_voxels [--resolutions=1024,2048,4096] [--rays=N] MESH... [benchmark flags]
//   MESH as kiln_bench_bvh takes it: a file, or LABEL=@DIR/PATTERN for many files as one scene.
//   Each benchmark keeps its fastest iteration; a Markdown table is printed at the end.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "bench_args.hpp"
#include "bench_timing.hpp"
#include "kiln/compiler/build.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/compiler/voxel_dag_builder.hpp"
#include "kiln/compiler/voxelizer.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/ray_structure.hpp"
#include "kiln/runtime/voxel_dag.hpp"
#include "kiln/tools/ray_generator.hpp"

namespace {

struct Settings {
  std::vector<std::uint32_t> resolutions{1024, 2048, 4096};
  std::size_t rays = 200000;
} g_settings;

struct Row {
  double voxelize_s = NAN, dag_s = NAN, cast_1t = NAN, cast_all = NAN;
  std::uint64_t voxels = 0, dag_bytes = 0, svo_bytes = 0, hits = 0;
};

struct Case {
  std::string label;
  kiln::Scene scene;
  std::vector<kiln::Ray> rays;
  std::map<std::uint32_t, Row> rows;
  std::map<std::uint32_t, std::shared_ptr<kiln::Voxels>> voxels;
  std::map<std::uint32_t, std::shared_ptr<kiln::FlatVoxelDag>> dags;
};
std::vector<std::unique_ptr<Case>> g_cases;

kiln::VoxelDagView view_of(const kiln::Voxels& v, const kiln::FlatVoxelDag& dag,
                           std::vector<std::uint64_t>& firsts) {
  firsts = kiln::level_first_words(dag);
  return kiln::VoxelDagView(dag.words, kiln::frame_of(v.grid), firsts, dag.leaf_first_word, {}, {});
}

void register_case(Case* c) {
  for (const std::uint32_t n : g_settings.resolutions) {
    const std::string prefix = c->label + "/" + std::to_string(n) + "/";
    benchmark::RegisterBenchmark((prefix + "voxelize").c_str(),
                                 [=](benchmark::State& state) {
                                   Row& row = c->rows[n];
                                   kiln::bench::timed(state, row.voxelize_s, [&] {
                                     c->voxels[n] = std::make_shared<kiln::Voxels>(
                                         kiln::voxelize_surface(c->scene, {n, false, 0}));
                                   });
                                   row.voxels = c->voxels[n]->codes.size();
                                 })
        ->UseManualTime()
        ->Iterations(2)
        ->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark(
        (prefix + "dag").c_str(),
        [=](benchmark::State& state) {
          Row& row = c->rows[n];
          if (!c->voxels[n])
            c->voxels[n] =
                std::make_shared<kiln::Voxels>(kiln::voxelize_surface(c->scene, {n, false, 0}));
          kiln::bench::timed(state, row.dag_s, [&] {
            c->dags[n] =
                std::make_shared<kiln::FlatVoxelDag>(kiln::build_voxel_dag(c->voxels[n]->codes, n));
          });
          row.voxels = c->voxels[n]->codes.size();
          row.dag_bytes = c->dags[n]->dag_bytes;
          row.svo_bytes = c->dags[n]->svo_bytes;
          std::vector<std::uint64_t>().swap(c->voxels[n]->codes);  // keep only what casts need
        })
        ->UseManualTime()
        ->Iterations(2)
        ->Unit(benchmark::kMillisecond);
    for (const unsigned threads : {1u, 0u}) {
      benchmark::RegisterBenchmark(
          (prefix + (threads == 1 ? "cast1T" : "castAll")).c_str(),
          [=](benchmark::State& state) {
            Row& row = c->rows[n];
            if (!c->dags[n]) {
              state.SkipWithError("run the dag benchmark first");
              return;
            }
            std::vector<std::uint64_t> firsts;
            const kiln::VoxelDagView view = view_of(*c->voxels[n], *c->dags[n], firsts);
            std::vector<kiln::VoxelHit> hits(c->rays.size());
            double best = NAN;
            kiln::bench::timed(state, best,
                               [&] { kiln::trace_rays(view, c->rays, hits, false, threads); });
            (threads == 1 ? row.cast_1t : row.cast_all) = double(c->rays.size()) / best * 1e-6;
            row.hits = std::count_if(hits.begin(), hits.end(), [](auto& h) { return h.hit(); });
          })
          ->UseManualTime()
          ->Iterations(3)
          ->Unit(benchmark::kMillisecond);
    }
  }
}

void print_report() {
  std::printf(
      "\n| mesh | resolution | voxels | voxelize s | DAG build s | DAG MB | bits/voxel | SVO MB | "
      "SVO/DAG | cast 1T Mrays/s | cast %uT Mrays/s | hit rays |\n",
      std::max(1u, std::thread::hardware_concurrency()));
  std::printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (const auto& c : g_cases)
    for (const auto& [n, r] : c->rows)
      std::printf(
          "| %s | %u^3 | %llu | %.3f | %.3f | %.2f | %.3f | %.2f | %.2f | %.2f | %.2f | %.1f %% "
          "|\n",
          c->label.c_str(), n, (unsigned long long)r.voxels, r.voxelize_s, r.dag_s,
          double(r.dag_bytes) / 1e6, double(r.dag_bytes) * 8 / double(r.voxels),
          double(r.svo_bytes) / 1e6, double(r.svo_bytes) / double(r.dag_bytes), r.cast_1t,
          r.cast_all, 100.0 * double(r.hits) / double(c->rays.size()));
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  std::vector<std::string> specs;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    try {
      if (kiln::bench::parse_list_option(arg, "resolutions", g_settings.resolutions) ||
          kiln::bench::parse_number_option(arg, "rays", g_settings.rays))
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
    std::fprintf(stderr, "usage: kiln_bench_voxels [--resolutions=1024,2048] [--rays=N] MESH...\n");
    return 2;
  }
  for (const auto& spec : specs) {
    auto c = std::make_unique<Case>();
    try {
      const auto mesh = kiln::bench::parse_mesh_spec(spec);
      if (!mesh) return 1;
      c->label = mesh->label;
      c->scene = kiln::import_scene(mesh->files, 0);
      const kiln::FlatBvh flat = kiln::build_bvh(c->scene, {});
      const kiln::BvhView bvh(flat.nodes, flat.triangles, flat.prim_ids);
      c->rays = kiln::generate_rays(
          {bvh, c->scene.positions, c->scene.triangles, c->scene.bounds.min, c->scene.bounds.max},
          kiln::RayKind::kPrimary, g_settings.rays, 1, 0);
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
