// SSVDAG against the voxel DAG on the same voxels: bytes and their ratio, build times, and ray
// casts per second (primary rays, closest voxel) on one thread and on all.
//
// Usage: kiln_bench_ssvdag [--resolutions=1024,2048] [--rays=N] MESH...
//   MESH as kiln_bench_bvh takes it: a file, or LABEL=@DIR/PATTERN for many files as one scene.
//   Builds: one run each (the voxelization is shared). Casts: fastest of 3. A plain main, no
//   Google Benchmark; prints a Markdown table.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <thread>
#include <vector>

#include "bench_args.hpp"
#include "kiln/compiler/build.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/compiler/ssvdag_builder.hpp"
#include "kiln/compiler/voxel_dag_builder.hpp"
#include "kiln/compiler/voxelizer.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/ray_structure.hpp"
#include "kiln/runtime/ssvdag.hpp"
#include "kiln/runtime/voxel_dag.hpp"
#include "kiln/tools/ray_generator.hpp"

namespace {

template <class Body>
double seconds(Body body) {
  const auto start = std::chrono::steady_clock::now();
  body();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Mrays/s, fastest of 3; `hits` gets the last run's hits.
template <class View>
double cast_rate(const View& view, const std::vector<kiln::Ray>& rays, unsigned threads,
                 std::vector<kiln::VoxelHit>& hits) {
  hits.assign(rays.size(), {});
  double best = INFINITY;
  for (int run = 0; run < 3; ++run)
    best = std::min(best, seconds([&] { kiln::trace_rays(view, rays, hits, false, threads); }));
  return double(rays.size()) / best * 1e-6;
}

void run_case(const std::string& label, const kiln::Scene& scene,
              const std::vector<kiln::Ray>& rays, std::uint32_t n) {
  kiln::Voxels voxels;
  const double voxelize_s = seconds([&] { voxels = kiln::voxelize_surface(scene, {n, false, 0}); });
  kiln::FlatVoxelDag dag;
  kiln::FlatSsvdag ssvdag;
  const double dag_s = seconds([&] { dag = kiln::build_voxel_dag(voxels.codes, n); });
  const double ssvdag_s = seconds([&] { ssvdag = kiln::build_ssvdag(voxels.codes, n, 0); });
  const std::uint64_t voxel_count = voxels.codes.size();
  std::vector<std::uint64_t>().swap(voxels.codes);
  const auto dag_firsts = kiln::level_first_words(dag);
  const auto ss_firsts = kiln::ssvdag_level_first_words(ssvdag);
  const kiln::VoxelDagView dag_view(dag.words, kiln::frame_of(voxels.grid), dag_firsts,
                                    dag.leaf_first_word, {}, {});
  const kiln::SsvdagView ss_view(ssvdag.words, ssvdag.leaves, kiln::frame_of(voxels.grid),
                                 ss_firsts, ssvdag.root_mirror);
  std::vector<kiln::VoxelHit> dag_hits, ss_hits;
  double rate[2][2];
  for (int t = 0; t < 2; ++t) {
    rate[0][t] = cast_rate(dag_view, rays, t == 0 ? 1 : 0, dag_hits);
    rate[1][t] = cast_rate(ss_view, rays, t == 0 ? 1 : 0, ss_hits);
  }
  std::size_t differ = 0;
  for (std::size_t i = 0; i < rays.size(); ++i)
    differ += dag_hits[i].x != ss_hits[i].x || dag_hits[i].y != ss_hits[i].y ||
              dag_hits[i].z != ss_hits[i].z || dag_hits[i].t != ss_hits[i].t;
  std::uint64_t wide = 0, narrow = 0;
  for (const auto& l : ssvdag.level_stats) wide += l.wide_pointers, narrow += l.narrow_pointers;
  std::printf(
      "| %s | %u^3 | %llu | %.2f | %.3f | %.3f | %.2f | %.2f | %.3f | %.3f | %.1f %% | %llu | "
      "%.2f | %.2f | %.2f | %.2f | %zu |\n",
      label.c_str(), n, (unsigned long long)voxel_count, voxelize_s, dag_s, ssvdag_s,
      double(dag.dag_bytes) / 1e6, double(ssvdag.ssvdag_bytes) / 1e6,
      double(ssvdag.ssvdag_bytes) / double(dag.dag_bytes),
      double(ssvdag.ssvdag_bytes) * 8 / double(voxel_count),
      100.0 * double(narrow) / double(std::max<std::uint64_t>(1, narrow + wide)),
      (unsigned long long)ssvdag.symmetry_merges, rate[0][0], rate[1][0], rate[0][1], rate[1][1],
      differ);
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::uint32_t> resolutions{1024, 2048};
  std::size_t ray_count = 200000;
  std::vector<std::string> specs;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    try {
      if (kiln::bench::parse_list_option(arg, "resolutions", resolutions) ||
          kiln::bench::parse_number_option(arg, "rays", ray_count))
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
    std::fprintf(stderr, "usage: kiln_bench_ssvdag [--resolutions=1024,2048] [--rays=N] MESH...\n");
    return 2;
  }
  std::printf(
      "| mesh | resolution | voxels | voxelize s | DAG build s | SSVDAG build s | DAG MB | "
      "SSVDAG MB | SSVDAG/DAG | SSVDAG bits/voxel | narrow pointers | merged by symmetry | "
      "DAG 1T Mrays/s | SSVDAG 1T Mrays/s | DAG %uT Mrays/s | SSVDAG %uT Mrays/s | hits differing "
      "|\n",
      std::max(1u, std::thread::hardware_concurrency()),
      std::max(1u, std::thread::hardware_concurrency()));
  std::printf(
      "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (const auto& spec : specs) {
    try {
      const auto mesh = kiln::bench::parse_mesh_spec(spec);
      if (!mesh) return 1;
      const kiln::Scene scene = kiln::import_scene(mesh->files, 0);
      const kiln::FlatBvh flat = kiln::build_bvh(scene, {});
      const kiln::BvhView bvh(flat.nodes, flat.triangles, flat.prim_ids);
      const auto rays = kiln::generate_rays(
          {bvh, scene.positions, scene.triangles, scene.bounds.min, scene.bounds.max},
          kiln::RayKind::kPrimary, ray_count, 1, 0);
      for (const std::uint32_t n : resolutions) run_case(mesh->label, scene, rays, n);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s\n", e.what());
      return 1;
    }
  }
  return 0;
}
