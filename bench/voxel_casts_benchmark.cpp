// Ray casts on the voxel structures of a built blob, at whatever resolution it was built (issue
// 20: casts per second up to 128K^3), and the conservative-hit property checked on a sample:
// every hit point lies within sqrt(3) finest voxels of the mesh (the voxel it lies in touches a
// triangle, and no point of a voxel is farther than its diagonal from that triangle).
//
// Usage: kiln_bench_voxel_casts BLOB [--rays=N] [--check=N] [--rounds=N]
// [--camera=EX,EY,EZ,TX,TY,TZ,FOV]
//   BLOB: a .kiln blob of triangles holding one or more voxel structures (--accel dag, ssvdag,
//   esvo). Rays: N primary rays (seed 1) framing the bounds, or from the camera. Casts are timed
//   on one thread and on all, `rounds` times each, medians. The check measures the distance from
//   each of the first `check` hit points to the mesh (closest point on a BVH of the blob's own
//   triangles) in finest voxels; ESVO's bound is its contour error instead (kiln dump says it).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "kiln/tools/ray_generator.hpp"

namespace {

struct Settings {
  std::string blob;
  std::size_t rays = 200000, check = 10000, rounds = 3;
  std::optional<kiln::RayCamera> camera;
};

bool parse_camera(const std::string& text, kiln::RayCamera& camera) {
  float v[7];
  if (std::sscanf(text.c_str(), "%f,%f,%f,%f,%f,%f,%f", &v[0], &v[1], &v[2], &v[3], &v[4], &v[5],
                  &v[6]) != 7)
    return false;
  camera = {{v[0], v[1], v[2]}, {v[3], v[4], v[5]}, v[6]};
  return true;
}

bool parse_args(int argc, char** argv, Settings& s) {
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto number = [&](const char* prefix, std::size_t& out) {
      if (!arg.starts_with(prefix)) return false;
      out = std::strtoull(arg.c_str() + std::strlen(prefix), nullptr, 10);
      return true;
    };
    if (number("--rays=", s.rays) || number("--check=", s.check) || number("--rounds=", s.rounds))
      continue;
    if (arg.starts_with("--camera=")) {
      kiln::RayCamera camera;
      if (!parse_camera(arg.substr(9), camera)) return false;
      s.camera = camera;
      continue;
    }
    if (arg.starts_with("-") || !s.blob.empty()) return false;
    s.blob = arg;
  }
  return !s.blob.empty() && s.rays > 0 && s.rounds > 0;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// Median seconds of `rounds` casts of every ray on `threads` threads (0 = all cores).
double time_casts(const kiln::RayQueries& rays, std::span<const kiln::Ray> set, unsigned threads,
                  std::size_t rounds) {
  std::vector<std::byte> records(set.size() * rays.record_size());
  std::vector<double> seconds;
  for (std::size_t r = 0; r < rounds; ++r) {
    const auto start = std::chrono::steady_clock::now();
    rays.trace_records(set, records, false, threads);
    seconds.push_back(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  return median(seconds);
}

struct Check {
  std::size_t hits = 0, checked = 0, beyond = 0;
  double max_voxels = 0, sum_voxels = 0;
};

// Distances, in finest voxels, from the hit points of the first rays to the mesh.
Check check_hits(const kiln::RayQueries& rays, const kiln::BvhView& mesh,
                 std::span<const kiln::Ray> set, double voxel_size, std::size_t limit) {
  Check c;
  for (const kiln::Ray& ray : set) {
    kiln::VoxelHit h;
    if (!rays.closest_voxel(ray, h) || !h.hit()) continue;
    ++c.hits;
    if (c.checked == limit) continue;
    const kiln::format::Float3 p{ray.org.x + h.t * ray.dir.x, ray.org.y + h.t * ray.dir.y,
                                 ray.org.z + h.t * ray.dir.z};
    const double d = kiln::closest_point(mesh, p, INFINITY).distance / voxel_size;
    ++c.checked;
    c.max_voxels = std::max(c.max_voxels, d);
    c.sum_voxels += d;
    // float hit points and distances: allow 1e-3 voxel of rounding at these coordinates
    if (d > std::sqrt(3.0) + 1e-3) ++c.beyond;
  }
  return c;
}

}  // namespace

int main(int argc, char** argv) {
  Settings s;
  if (!parse_args(argc, argv, s)) {
    std::fprintf(stderr,
                 "usage: kiln_bench_voxel_casts BLOB [--rays=N] [--check=N] [--rounds=N] "
                 "[--camera=EX,EY,EZ,TX,TY,TZ,FOV]\n");
    return 2;
  }
  try {
    const kiln::Blob blob = kiln::Blob::open_file(s.blob);
    kiln::Scene scene;
    scene.positions.assign(blob.positions().begin(), blob.positions().end());
    scene.triangles.assign(blob.triangles().begin(), blob.triangles().end());
    scene.bounds = {blob.input().bounds.min, blob.input().bounds.max};
    const kiln::FlatBvh flat = kiln::build_bvh(scene, {});
    const kiln::BvhView mesh(flat.nodes, flat.triangles, flat.prim_ids);
    const kiln::RayScene ray_scene{mesh, scene.positions, scene.triangles, scene.bounds.min,
                                   scene.bounds.max};
    const std::vector<kiln::Ray> set =
        s.camera ? kiln::generate_rays(ray_scene, *s.camera, kiln::RayKind::kPrimary, s.rays, 1, 0)
                 : kiln::generate_rays(ray_scene, kiln::RayKind::kPrimary, s.rays, 1, 0);
    std::printf(
        "| structure | resolution | rays | hits | 1T Mrays/s | %uT Mrays/s | checked | "
        "max distance (voxels) | mean | beyond sqrt(3) |\n|---|---:|---:|---:|---:|---:|---:|"
        "---:|---:|---:|\n",
        std::max(1u, std::thread::hardware_concurrency()));
    for (const kiln::StructureInfo& info : blob.structures()) {
      const auto view = kiln::open_structure(blob, info.name);
      const kiln::RayQueries* rays = view->rays();
      kiln::VoxelGridFrame frame;
      if (rays == nullptr || !rays->voxel_frame(frame)) continue;
      const double one = time_casts(*rays, set, 1, s.rounds);
      const double all = time_casts(*rays, set, 0, s.rounds);
      const Check c = check_hits(*rays, mesh, set, frame.voxel_size, s.check);
      std::printf("| %s | %u^3 | %zu | %zu | %.2f | %.2f | %zu | %.3f | %.3f | %zu |\n",
                  info.name.c_str(), frame.resolution, set.size(), c.hits, set.size() / one / 1e6,
                  set.size() / all / 1e6, c.checked, c.max_voxels,
                  c.checked ? c.sum_voxels / double(c.checked) : 0.0, c.beyond);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "kiln_bench_voxel_casts: %s\n", e.what());
    return 1;
  }
  return 0;
}
