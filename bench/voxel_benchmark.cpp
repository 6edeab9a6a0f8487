// Voxel DAG: voxelization and DAG construction time, sizes per resolution, and ray casts per
// second (single thread and all threads) on primary rays.
//
// Usage: kiln_bench_voxels [--resolutions=1024,2048,4096] [--rays=N] MESH... [benchmark flags]
//        kiln_bench_voxels --speed [--resolutions=...] [--repeats=N] [--normals] [--no-before]
//                          [--no-codes] MESH...
//   --speed: surface voxelization alone (issue 20), the leaves path and the codes path against the
//   voxelizer before issue 20 (a copy below), alternating before/after; wall and CPU time.
//   MESH as kiln_bench_bvh takes it: a file, or LABEL=@DIR/PATTERN for many files as one scene.
//   Each benchmark keeps its fastest iteration; a Markdown table is printed at the end.
#include <benchmark/benchmark.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
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
#include "kiln/formats/voxel_grid.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/parallel.hpp"
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

// The surface voxelizer as it was before issue 20 (commit 7e32b11), for before/after timings in
// one process: per triangle and column the exact predicate voxel by voxel, then per 128^3 brick a
// sort of (code, triangle) pairs. Codes only (the leaves path was leaves_of(codes)).
namespace before {

struct VoxelRange {
  std::int64_t lo[3], hi[3];
};

VoxelRange candidate_range(const kiln::GridTriangle& t, const VoxelRange& clip) {
  VoxelRange r;
  for (int a = 0; a < 3; ++a) {
    const double lo = std::min(
        {kiln::format::at(t.v[0], a), kiln::format::at(t.v[1], a), kiln::format::at(t.v[2], a)});
    const double hi = std::max(
        {kiln::format::at(t.v[0], a), kiln::format::at(t.v[1], a), kiln::format::at(t.v[2], a)});
    r.lo[a] = std::max(clip.lo[a], std::int64_t(std::ceil(lo)) - 1);
    r.hi[a] = std::min(clip.hi[a], std::int64_t(std::floor(hi)));
  }
  return r;
}

template <class Emit>
void voxelize_triangle(const kiln::GridTriangle& t, const VoxelRange& clip, Emit emit) {
  const VoxelRange r = candidate_range(t, clip);
  if (r.lo[0] > r.hi[0] || r.lo[1] > r.hi[1] || r.lo[2] > r.hi[2]) return;
  const kiln::format::Double3 n = cross(t.v[1] - t.v[0], t.v[2] - t.v[0]);
  int a = 0;
  for (int i = 1; i < 3; ++i)
    if (std::fabs(kiln::format::at(n, i)) > std::fabs(kiln::format::at(n, a))) a = i;
  const double na = kiln::format::at(n, a), nu = kiln::format::at(n, (a + 1) % 3),
               nv = kiln::format::at(n, (a + 2) % 3);
  const int u = (a + 1) % 3, v = (a + 2) % 3;
  const double d = dot(n, t.v[0]);
  for (std::int64_t iu = r.lo[u]; iu <= r.hi[u]; ++iu)
    for (std::int64_t iv = r.lo[v]; iv <= r.hi[v]; ++iv) {
      double amin = INFINITY, amax = -INFINITY;
      for (const double cu : {double(iu), double(iu + 1)})
        for (const double cv : {double(iv), double(iv + 1)}) {
          const double at = (d - nu * cu - nv * cv) / na;
          amin = std::min(amin, at), amax = std::max(amax, at);
        }
      const std::int64_t lo = std::max(r.lo[a], std::int64_t(std::floor(amin)) - 1);
      const std::int64_t hi = std::min(r.hi[a], std::int64_t(std::floor(amax)) + 1);
      for (std::int64_t ia = lo; ia <= hi; ++ia) {
        std::int64_t c[3];
        c[a] = ia, c[u] = iu, c[v] = iv;
        if (kiln::triangle_touches_voxel(t, std::uint32_t(c[0]), std::uint32_t(c[1]),
                                         std::uint32_t(c[2])))
          emit(std::uint32_t(c[0]), std::uint32_t(c[1]), std::uint32_t(c[2]));
      }
    }
}

kiln::GridTriangle grid_triangle(const kiln::Scene& scene, const kiln::VoxelGrid& grid,
                                 std::uint32_t i) {
  const auto& tri = scene.triangles[i];
  return kiln::to_grid(grid, scene.positions[tri.v[0]], scene.positions[tri.v[1]],
                       scene.positions[tri.v[2]]);
}

std::vector<std::uint64_t> voxelize_codes(const kiln::Scene& scene, const kiln::VoxelGrid& grid,
                                          unsigned threads) {
  const std::uint32_t brick = std::min(grid.resolution, 128u), per_axis = grid.resolution / brick;
  const VoxelRange whole{{0, 0, 0},
                         {grid.resolution - 1, grid.resolution - 1, grid.resolution - 1}};
  std::vector<std::vector<std::uint32_t>> bins(std::size_t(per_axis) * per_axis * per_axis);
  for (std::uint32_t i = 0; i < scene.triangles.size(); ++i) {
    const VoxelRange r = candidate_range(grid_triangle(scene, grid, i), whole);
    if (r.lo[0] > r.hi[0] || r.lo[1] > r.hi[1] || r.lo[2] > r.hi[2]) continue;
    for (auto bz = r.lo[2] / brick; bz <= r.hi[2] / brick; ++bz)
      for (auto by = r.lo[1] / brick; by <= r.hi[1] / brick; ++by)
        for (auto bx = r.lo[0] / brick; bx <= r.hi[0] / brick; ++bx)
          bins[kiln::format::morton_code(std::uint32_t(bx), std::uint32_t(by), std::uint32_t(bz))]
              .push_back(i);
  }
  std::vector<std::vector<std::uint64_t>> bricks(bins.size());
  kiln::parallel_for(bins.size(), threads, [&](std::size_t b) {
    if (bins[b].empty()) return;
    VoxelRange clip;
    const std::uint32_t local[3] = {kiln::format::compact_bits(b),
                                    kiln::format::compact_bits(b >> 1),
                                    kiln::format::compact_bits(b >> 2)};
    for (int a = 0; a < 3; ++a)
      clip.lo[a] = std::int64_t(local[a]) * brick, clip.hi[a] = clip.lo[a] + brick - 1;
    std::vector<std::pair<std::uint64_t, std::uint32_t>> hits;
    for (const std::uint32_t i : bins[b])
      voxelize_triangle(grid_triangle(scene, grid, i), clip,
                        [&](std::uint32_t x, std::uint32_t y, std::uint32_t z) {
                          hits.emplace_back(kiln::format::morton_code(x, y, z), i);
                        });
    std::sort(hits.begin(), hits.end());
    for (std::size_t k = 0; k < hits.size(); ++k)
      if (k == 0 || hits[k].first != hits[k - 1].first) bricks[b].push_back(hits[k].first);
  });
  std::vector<std::uint64_t> codes;
  for (auto& b : bricks) codes.insert(codes.end(), b.begin(), b.end()), b = {};
  return codes;
}

}  // namespace before

// Wall and CPU seconds (this process, all threads) of body().
template <class Body>
std::pair<double, double> wall_and_cpu(Body body) {
  auto cpu = [] {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
           1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
  };
  const double c0 = cpu();
  const auto w0 = std::chrono::steady_clock::now();
  body();
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - w0).count();
  return {wall, cpu() - c0};
}

struct SpeedSettings {
  bool on = false, normals = false, skip_before = false, skip_codes = false;
  std::size_t repeats = 2;
} g_speed;

// One mesh at each resolution: before (codes), after (leaves), after (codes), alternating, the
// fastest of `repeats` by CPU time; checks that all paths give the same voxels.
int run_speed(const std::string& label, const kiln::Scene& scene) {
  const unsigned threads = kiln::resolve_thread_count(0);
  for (const std::uint32_t n : g_settings.resolutions) {
    const kiln::VoxelGrid grid = kiln::fit_voxel_grid(scene.bounds, n);
    std::vector<std::uint32_t> all(scene.triangles.size());
    for (std::uint32_t i = 0; i < all.size(); ++i) all[i] = i;
    const kiln::VoxelCube cube{{0, 0, 0}, n};
    struct Best {
      double wall = INFINITY, cpu = INFINITY;
    } before_t, leaves_t, codes_t, normals_t;
    std::uint64_t voxels = 0, leaf_count = 0;
    auto keep = [](Best& b, std::pair<double, double> t) {
      if (t.second < b.cpu) b.wall = t.first, b.cpu = t.second;
    };
    std::vector<std::uint64_t> reference;
    kiln::VoxelLeaves reference_leaves;
    for (std::size_t r = 0; r < g_speed.repeats; ++r) {
      if (!g_speed.skip_before)
        keep(before_t, wall_and_cpu([&] {
               reference = before::voxelize_codes(scene, grid, threads);
               reference_leaves = kiln::leaves_of(reference);  // the old leaves path
             }));
      kiln::VoxelLeaves leaves;
      keep(leaves_t, wall_and_cpu([&] {
             leaves = kiln::voxelize_surface_leaves(scene, grid, cube, all, threads);
           }));
      voxels = leaves.voxel_count, leaf_count = leaves.keys.size();
      bool same = g_speed.skip_before ||
                  (leaves.keys == reference_leaves.keys && leaves.masks == reference_leaves.masks);
      leaves = {};
      if (!g_speed.skip_codes) {
        std::vector<std::uint64_t> codes;
        keep(codes_t, wall_and_cpu([&] {
               codes = kiln::voxelize_surface_cube(scene, grid, cube, all, false, threads).codes;
             }));
        same = same && (g_speed.skip_before || codes == reference);
      }
      if (!same) {
        std::fprintf(stderr, "%s %u^3: the voxel sets differ from before\n", label.c_str(), n);
        return 1;
      }
      if (g_speed.normals)
        keep(normals_t, wall_and_cpu([&] {
               kiln::voxelize_surface_cube(scene, grid, cube, all, true, threads);
             }));
    }
    auto row = [&](const char* path, const Best& b) {
      if (std::isinf(b.cpu)) return;
      std::printf("| %s | %u^3 | %s | %llu | %llu | %.2f | %.2f | %.1f | %.1f |\n", label.c_str(),
                  n, path, (unsigned long long)voxels, (unsigned long long)leaf_count, b.wall,
                  b.cpu, double(voxels) / b.wall * 1e-6, double(voxels) / b.cpu * threads * 1e-6);
      std::fflush(stdout);
    };
    row("before: codes + leaves_of", before_t);
    row("after: leaves", leaves_t);
    row("after: codes", codes_t);
    row("after: codes + normals", normals_t);
  }
  return 0;
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
          kiln::bench::parse_number_option(arg, "repeats", g_speed.repeats))
        continue;
      if (arg == "--speed" || arg == "--normals" || arg == "--no-before" || arg == "--no-codes") {
        (arg == "--speed"       ? g_speed.on
         : arg == "--normals"   ? g_speed.normals
         : arg == "--no-before" ? g_speed.skip_before
                                : g_speed.skip_codes) = true;
        continue;
      }
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
  if (g_speed.on) {
    std::printf(
        "| mesh | resolution | path | voxels | leaves | wall s | CPU s | M voxels/s (wall) "
        "| M voxels/s per CPU s x %u |\n|---|---:|---|---:|---:|---:|---:|---:|---:|\n",
        kiln::resolve_thread_count(0));
    for (const auto& spec : specs) {
      try {
        const auto mesh = kiln::bench::parse_mesh_spec(spec);
        if (!mesh) return 1;
        if (run_speed(mesh->label, kiln::import_scene(mesh->files, 0)) != 0) return 1;
      } catch (const std::exception& e) {
        std::fprintf(stderr, "%s\n", e.what());
        return 1;
      }
    }
    return 0;
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
