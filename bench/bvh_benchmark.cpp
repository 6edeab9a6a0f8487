// Build and traversal throughput of Kiln's ray structures (BVH with the binned SAH, full-sweep SAH
// and SBVH builders; the SAH k-d tree) and, when built with -DKILN_BENCH_EMBREE=ON, of Embree 3
// on the same triangles and the same rays.
//
// Usage: kiln_bench_bvh [--rays=N] [--seed=N] [--iterations=N] [--rounds=N]
//                       [--camera=EX,EY,EZ,TX,TY,TZ,FOV] MESH... [benchmark flags]
//   MESH    a file import_scene reads (OBJ, PLY, .drc, any of them .zst...), or
//           [LABEL=]@DIR[/PATTERN]: every file in DIR matching PATTERN (default *.obj), sorted by
//           name, imported as one scene, e.g.
//           'sponza=@/tmp/sponza/crytek-sponza/models/sponza_*.obj'
//   --rays  rays per kind (primary, diffuse, shadow); default 200000
//   --seed  ray generator seed; default 1
//   --iterations  timed repetitions of every benchmark; default 0 = by mesh size
//   --rounds  instead of the benchmarks: N rounds that trace every ray set once with each Kiln
//           layout and kernel and each Embree scene, alternately in one process; reports the
//           median Mrays/s and the median of the per-round Kiln ÷ Embree ratios
//   --camera  primary rays (and the hits diffuse and shadow rays start from) from this pinhole
//           camera, for the meshes named after it (--camera=none: frame the bounds again)
//   --only=NAME,...  (--rounds) only the contestants of these names (e.g. "sbvh w8 avx2,embree
//           high"); --one-thread: (--rounds) skip the all-threads passes
//   --collapse=LABEL:NODE:PACKET:MAXREFS[:LEAF[:ORDER]] or LABEL:greedy
//           (--rounds, repeatable) one more contestant "sbvh w8 LABEL" (default kernel): the
//           SBVH collapsed with these costs and slot order (0 tree, 1 largest area, 2 occlusion)
//   --collapse-width=W  the --collapse variants' width (8 unless given; 4 or 16)
//   --sbvh-build=LABEL:TRAV:ISECT:MAXLEAF[:ALPHA]  the --collapse variant LABEL collapses an SBVH
//           built with these SAH costs, leaf size and spatial-split threshold (default 1:1:8:1e-5)
//
// Every benchmark times itself with std::chrono (manual time) and keeps its fastest iteration,
// which feeds the counters and the Markdown tables printed at the end: on a small, shared machine
// the minimum is the least noisy estimate.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <exception>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <type_traits>
#include <vector>

#include "bench_args.hpp"
#include "kiln/compiler/build.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/compiler/bvh_collapse.hpp"
#include "kiln/compiler/kdtree_builder.hpp"
#include "kiln/runtime/aligned_buffer.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/bvh_wide.hpp"
#include "kiln/runtime/kdtree.hpp"
#include "kiln/runtime/ray.hpp"
#include "kiln/runtime/ray_structure.hpp"
#include "kiln/tools/ray_generator.hpp"

#ifdef KILN_BENCH_EMBREE
#include <embree3/rtcore.h>
#endif

namespace {

using Clock = std::chrono::steady_clock;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

unsigned hardware_threads() {
  return std::max(1u, std::thread::hardware_concurrency());
}

// ---------------------------------------------------------------------------------------------
// What is measured: one row per acceleration structure and mesh.

enum class Structure { kBinned, kSweep, kSbvh, kKdTree, kEmbreeMedium, kEmbreeHigh };
constexpr std::array kStructures = {Structure::kBinned,       Structure::kSweep,
                                    Structure::kSbvh,         Structure::kKdTree,
                                    Structure::kEmbreeMedium, Structure::kEmbreeHigh};

const char* structure_name(Structure s) {
  switch (s) {
    case Structure::kBinned:
      return "binned";
    case Structure::kSweep:
      return "sweep";
    case Structure::kSbvh:
      return "sbvh";
    case Structure::kKdTree:
      return "kdtree";
    case Structure::kEmbreeMedium:
      return "embree-medium";
    case Structure::kEmbreeHigh:
      return "embree-high";
  }
  return "?";
}

kiln::BvhBuilder kiln_builder(Structure s) {
  return s == Structure::kBinned  ? kiln::BvhBuilder::kBinned
         : s == Structure::kSweep ? kiln::BvhBuilder::kSweep
                                  : kiln::BvhBuilder::kSpatial;
}

constexpr std::array kRayKinds = {kiln::RayKind::kPrimary, kiln::RayKind::kDiffuse,
                                  kiln::RayKind::kShadow};

const char* ray_kind_name(kiln::RayKind kind) {
  switch (kind) {
    case kiln::RayKind::kPrimary:
      return "primary";
    case kiln::RayKind::kDiffuse:
      return "diffuse";
    case kiln::RayKind::kShadow:
      return "shadow";
  }
  return "?";
}

// Shadow rays only ask whether anything blocks them; the others want the closest hit.
bool is_any_hit(kiln::RayKind kind) {
  return kind == kiln::RayKind::kShadow;
}

std::size_t kind_index(kiln::RayKind kind) {
  return std::size_t(std::find(kRayKinds.begin(), kRayKinds.end(), kind) - kRayKinds.begin());
}

struct Row {
  double build_seconds = kNaN;
  double sah_cost = kNaN;
  double bytes_per_triangle = kNaN;
  // [ray kind][0: one thread, 1: all threads]
  std::array<std::array<double, 2>, kRayKinds.size()> mrays{
      {{kNaN, kNaN}, {kNaN, kNaN}, {kNaN, kNaN}}};
};

// ---------------------------------------------------------------------------------------------
// Embree: a device shared by every benchmark and one committed scene per (mesh, quality).

#ifdef KILN_BENCH_EMBREE

// Embree's hit/miss against Kiln's SBVH on one ray set (checked once, outside timing).
struct Agreement {
  Structure embree;
  kiln::RayKind kind;
  std::size_t rays = 0, same_hit_or_miss = 0, same_prim = 0;
  double fraction() const { return rays ? double(same_hit_or_miss) / double(rays) : 0; }
};

// Net bytes Embree holds (allocations minus frees), from its memory monitor: the difference
// across rtcCommitScene is what the built structure keeps (BVH, primitive blocks, slack).
std::atomic<std::int64_t> g_embree_bytes{0};

bool track_embree_memory(void*, ssize_t bytes, bool) {
  g_embree_bytes += bytes;
  return true;
}

RTCDevice embree_device() {
  static RTCDevice device = [] {
    RTCDevice d = rtcNewDevice(nullptr);
    if (!d) {
      std::fprintf(stderr, "rtcNewDevice failed: %d\n", int(rtcGetDeviceError(nullptr)));
      std::exit(1);
    }
    // An Embree error means the comparison is meaningless: stop loudly.
    rtcSetDeviceErrorFunction(
        d,
        [](void*, RTCError code, const char* message) {
          std::fprintf(stderr, "Embree error %d: %s\n", int(code), message ? message : "");
          std::abort();
        },
        nullptr);
    rtcSetDeviceMemoryMonitorFunction(d, track_embree_memory, nullptr);
    return d;
  }();
  return device;
}

RTCBuildQuality embree_quality(Structure s) {
  return s == Structure::kEmbreeHigh ? RTC_BUILD_QUALITY_HIGH : RTC_BUILD_QUALITY_MEDIUM;
}

struct EmbreeSceneDeleter {
  void operator()(RTCSceneTy* scene) const { rtcReleaseScene(scene); }
};
using EmbreeScene = std::unique_ptr<RTCSceneTy, EmbreeSceneDeleter>;

// A scene holding one triangle geometry with copies of the vertices and indices, not yet
// committed (the commit is the build being timed). rtcSetNewGeometryBuffer pads the vertex
// buffer as Embree's SIMD loads require, which sharing the Scene's arrays would not.
EmbreeScene make_embree_scene(const kiln::Scene& scene, RTCBuildQuality quality,
                              RTCSceneFlags flags = RTC_SCENE_FLAG_NONE) {
  const RTCDevice device = embree_device();
  RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vertices = static_cast<kiln::format::Float3*>(
      rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                              sizeof(kiln::format::Float3), scene.positions.size()));
  std::copy(scene.positions.begin(), scene.positions.end(), vertices);
  auto* indices = static_cast<kiln::format::Triangle*>(
      rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                              sizeof(kiln::format::Triangle), scene.triangles.size()));
  std::copy(scene.triangles.begin(), scene.triangles.end(), indices);
  rtcSetGeometryBuildQuality(geometry, quality);
  rtcCommitGeometry(geometry);

  EmbreeScene out(rtcNewScene(device));
  rtcSetSceneBuildQuality(out.get(), quality);
  rtcSetSceneFlags(out.get(), flags);
  rtcAttachGeometry(out.get(), geometry);
  rtcReleaseGeometry(geometry);  // the scene holds it now
  return out;
}

// Kiln's Ray in Embree's layout. Done per ray inside the timed loops: a renderer built on
// Embree would fill RTCRayHit directly, but the copy is a few stores against a traversal.
RTCRayHit to_embree(const kiln::Ray& r) {
  RTCRayHit rh;
  rh.ray.org_x = r.org.x;
  rh.ray.org_y = r.org.y;
  rh.ray.org_z = r.org.z;
  rh.ray.tnear = r.tmin;
  rh.ray.dir_x = r.dir.x;
  rh.ray.dir_y = r.dir.y;
  rh.ray.dir_z = r.dir.z;
  rh.ray.time = 0;
  rh.ray.tfar = r.tmax;
  rh.ray.mask = ~0u;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  return rh;
}

// One ray traced with Embree, its result written as a kiln::Hit (any hit: prim 0 or kNoHit).
kiln::Hit embree_trace(RTCScene scene, const kiln::Ray& ray, bool any_hit) {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh = to_embree(ray);
  kiln::Hit hit;
  if (any_hit) {
    rtcOccluded1(scene, &context, &rh.ray);
    // Embree marks an occluded ray by setting tfar to -inf.
    if (rh.ray.tfar < 0) hit.prim = 0;
    return hit;
  }
  rtcIntersect1(scene, &context, &rh);
  if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID)
    hit = {rh.ray.tfar, rh.hit.primID, rh.hit.u, rh.hit.v};
  return hit;
}

#endif  // KILN_BENCH_EMBREE

// ---------------------------------------------------------------------------------------------
// One mesh (or multi-file scene) under test. Structures and rays are made on first use, so that
// a --benchmark_filter selecting only traversal still works; the build benchmarks leave their
// last result here for the traversal benchmarks to reuse.

struct MeshCase {
  std::string label;
  std::vector<std::string> files;
  kiln::Scene scene;
  std::map<std::pair<kiln::BvhBuilder, bool>, kiln::FlatBvh> bvhs;  // by builder, for wide
  std::map<std::string, kiln::FlatBvh> variant_bvhs;                // --sbvh-build, by label
  std::optional<kiln::FlatKdTree> kdtree;
  std::map<kiln::RayKind, std::vector<kiln::Ray>> rays;
  std::map<Structure, Row> rows;
  std::optional<kiln::RayCamera> camera;  // primary rays from here, else framing the bounds
#ifdef KILN_BENCH_EMBREE
  std::map<Structure, EmbreeScene> embree;
#endif
};

struct Settings {
  std::size_t rays = 200000;
  std::uint64_t seed = 1;
  int iterations = 0;             // 0: by mesh size
  int rounds = 0;                 // > 0: the alternating comparison instead of the benchmarks
  std::vector<std::string> only;  // --rounds: contestants kept (empty: all)
  bool one_thread = false;        // --rounds: no all-threads passes
  std::vector<std::pair<std::string, kiln::WideCollapseOptions>> collapses;
  std::uint32_t collapse_width = 8;  // --collapse-width: the width of the --collapse variants
  std::map<std::string, kiln::BvhBuildOptions> sbvh_builds;  // --sbvh-build, by collapse label
};

Settings g_settings;
std::vector<std::unique_ptr<MeshCase>> g_meshes;
#ifdef KILN_BENCH_EMBREE
std::vector<std::pair<const MeshCase*, Agreement>> g_agreements;
#endif

const kiln::FlatBvh& bvh_for(MeshCase& mesh, kiln::BvhBuilder builder, bool for_wide = false);

// The SBVH a --collapse variant collapses: built with its --sbvh-build options, if any, else as
// `kiln build` builds it for the wide layouts.
const kiln::FlatBvh& sbvh_for_variant(MeshCase& mesh, const std::string& label) {
  const auto options = g_settings.sbvh_builds.find(label);
  if (options == g_settings.sbvh_builds.end())
    return bvh_for(mesh, kiln::BvhBuilder::kSpatial, true);
  auto it = mesh.variant_bvhs.find(label);
  if (it == mesh.variant_bvhs.end())
    it = mesh.variant_bvhs.emplace(label, kiln::build_bvh(mesh.scene, options->second)).first;
  return it->second;
}

// The binary tree of `builder`; `for_wide`: as `kiln build` builds it for the wide layouts, its
// leaves priced per packet (BvhBuildOptions::leaf_packet).
const kiln::FlatBvh& bvh_for(MeshCase& mesh, kiln::BvhBuilder builder, bool for_wide) {
  auto it = mesh.bvhs.find({builder, for_wide});
  if (it == mesh.bvhs.end()) {
    kiln::BvhBuildOptions options;
    options.builder = builder;
    options.threads = 0;
    if (for_wide) options.leaf_packet = kiln::format::kBvhPacketSize;
    it =
        mesh.bvhs.emplace(std::pair{builder, for_wide}, kiln::build_bvh(mesh.scene, options)).first;
  }
  return it->second;
}

const kiln::FlatKdTree& kdtree_for(MeshCase& mesh) {
  if (!mesh.kdtree) mesh.kdtree.emplace(kiln::build_kdtree(mesh.scene, {}));
  return *mesh.kdtree;
}

kiln::KdTreeView kdtree_view(const kiln::FlatKdTree& t) {
  return kiln::KdTreeView(t.nodes, t.prim_ids, t.triangles, t.bounds);
}

// The same rays for every structure: generated once from the binned BVH (any correct BVH gives
// the generator the same closest hits, so the choice does not change the rays' distribution).
const std::vector<kiln::Ray>& rays_for(MeshCase& mesh, kiln::RayKind kind) {
  auto it = mesh.rays.find(kind);
  if (it == mesh.rays.end()) {
    const kiln::FlatBvh& flat = bvh_for(mesh, kiln::BvhBuilder::kBinned);
    const kiln::BvhView bvh(flat.nodes, flat.triangles, flat.prim_ids);
    const kiln::RayScene ray_scene{bvh, mesh.scene.positions, mesh.scene.triangles,
                                   mesh.scene.bounds.min, mesh.scene.bounds.max};
    it = mesh.rays
             .emplace(kind, mesh.camera ? kiln::generate_rays(ray_scene, *mesh.camera, kind,
                                                              g_settings.rays, g_settings.seed, 0)
                                        : kiln::generate_rays(ray_scene, kind, g_settings.rays,
                                                              g_settings.seed, 0))
             .first;
  }
  return it->second;
}

#ifdef KILN_BENCH_EMBREE
RTCScene embree_for(MeshCase& mesh, Structure s) {
  auto it = mesh.embree.find(s);
  if (it == mesh.embree.end()) {
    EmbreeScene scene = make_embree_scene(mesh.scene, embree_quality(s));
    rtcCommitScene(scene.get());
    it = mesh.embree.emplace(s, std::move(scene)).first;
  }
  return it->second.get();
}
#endif

// ---------------------------------------------------------------------------------------------
// Tracing loops shared by Kiln and Embree.

// Runs trace(i) for every ray on all hardware threads, in batches of 4096 rays handed out from
// an atomic counter: the same scheduling as kiln::trace_rays, so both sides pay alike for it.
// A template, not std::function: no indirect call per ray that Kiln's loop does not pay.
template <typename Trace>
void for_each_ray_parallel(std::size_t count, const Trace& trace) {
  constexpr std::size_t kBatch = 4096;
  const std::size_t batches = (count + kBatch - 1) / kBatch;
  std::atomic<std::size_t> next{0};
  auto worker = [&] {
    for (std::size_t b = next++; b < batches; b = next++) {
      const std::size_t end = std::min(count, (b + 1) * kBatch);
      for (std::size_t i = b * kBatch; i < end; ++i) trace(i);
    }
  };
  std::vector<std::jthread> pool;
  for (unsigned t = 1; t < hardware_threads(); ++t) pool.emplace_back(worker);
  worker();
}

template <class View>
void trace_kiln_single(const View& bvh, const std::vector<kiln::Ray>& rays,
                       std::vector<kiln::Hit>& hits, bool any_hit) {
  for (std::size_t i = 0; i < rays.size(); ++i) {
    if (any_hit) {
      hits[i].prim = bvh.occluded(rays[i]) ? 0 : kiln::kNoHit;
    } else {
      hits[i] = bvh.intersect(rays[i]);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Benchmarks. Each keeps its fastest iteration (see the file comment).

int iterations_for(const MeshCase& mesh, bool build) {
  if (g_settings.iterations > 0) return g_settings.iterations;
  // Builds of big meshes take seconds on two cores: two of them (the first also pays for page
  // faults and thread-pool start-up). A pass over the rays takes well under a second.
  if (build) return mesh.scene.triangles.size() > 200000 ? 2 : 3;
  return 5;
}

// Times body() once per iteration, after an untimed prepare(); returns the fastest time in seconds.
double time_iterations(
    benchmark::State& state, const std::function<void()>& body,
    const std::function<void()>& prepare = [] {}) {
  double best = std::numeric_limits<double>::infinity();
  for (auto _ : state) {
    prepare();
    const auto start = Clock::now();
    body();
    const double seconds = seconds_since(start);
    state.SetIterationTime(seconds);
    best = std::min(best, seconds);
  }
  return best;
}

void set_build_counters(benchmark::State& state, const MeshCase& mesh, const Row& row) {
  state.counters["Mtris/s"] = double(mesh.scene.triangles.size()) / row.build_seconds * 1e-6;
  if (!std::isnan(row.sah_cost)) state.counters["SAH"] = row.sah_cost;  // Embree's is not exposed
  state.counters["B/tri"] = row.bytes_per_triangle;
}

// The k-d tree's SAH cost uses its own constants (Ct 15, Ci 20); divided by Ci it counts triangle
// tests, as the BVH's (Ct 1, Ci 1) does, so the column compares like with like.
void bench_kiln_kdtree_build(benchmark::State& state, MeshCase* mesh) {
  const kiln::KdTreeBuildOptions options;
  std::optional<kiln::FlatKdTree> built;
  Row& row = mesh->rows[Structure::kKdTree];
  row.build_seconds = time_iterations(
      state, [&] { built.emplace(kiln::build_kdtree(mesh->scene, options)); },
      [&] { built.reset(); });
  row.sah_cost = built->stats.sah_cost / options.intersection_cost;
  row.bytes_per_triangle = built->stats.bytes_per_triangle;
  set_build_counters(state, *mesh, row);
  mesh->kdtree = std::move(built);
}

void bench_kiln_build(benchmark::State& state, MeshCase* mesh, Structure s) {
  if (s == Structure::kKdTree) return bench_kiln_kdtree_build(state, mesh);
  kiln::BvhBuildOptions options;
  options.builder = kiln_builder(s);
  options.threads = 0;
  std::optional<kiln::FlatBvh> built;
  Row& row = mesh->rows[s];
  row.build_seconds = time_iterations(
      state, [&] { built.emplace(kiln::build_bvh(mesh->scene, options)); },
      [&] { built.reset(); });  // freeing the previous result is not part of a build
  row.sah_cost = built->stats.sah_cost;
  row.bytes_per_triangle = built->stats.bytes_per_triangle;
  set_build_counters(state, *mesh, row);
  mesh->bvhs[{options.builder, false}] = std::move(*built);
}

void bench_kiln_trace(benchmark::State& state, MeshCase* mesh, Structure s, kiln::RayKind kind,
                      bool all_threads) {
  const std::vector<kiln::Ray>* rays = nullptr;
  try {
    rays = &rays_for(*mesh, kind);
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  std::vector<kiln::Hit> hits(rays->size());
  const bool any_hit = is_any_hit(kind);
  auto time_view = [&](const auto& view) {
    return time_iterations(state, [&] {
      if (all_threads) {
        kiln::trace_rays(view, *rays, hits, any_hit, 0);
      } else {
        trace_kiln_single(view, *rays, hits, any_hit);
      }
      benchmark::ClobberMemory();
    });
  };
  double seconds = 0;
  if (s == Structure::kKdTree) {
    seconds = time_view(kdtree_view(kdtree_for(*mesh)));  // the view's O(nodes) check: untimed
  } else {
    const kiln::FlatBvh& flat = bvh_for(*mesh, kiln_builder(s));
    seconds = time_view(kiln::BvhView(flat.nodes, flat.triangles, flat.prim_ids));
  }
  const double mrays = double(rays->size()) / seconds * 1e-6;
  state.counters["Mrays/s"] = mrays;
  mesh->rows[s].mrays[kind_index(kind)][all_threads] = mrays;
}

#ifdef KILN_BENCH_EMBREE
void bench_embree_build(benchmark::State& state, MeshCase* mesh, Structure s) {
  EmbreeScene scene;
  std::int64_t before = 0, after = 0;
  Row& row = mesh->rows[s];
  // A fresh, uncommitted scene per iteration (buffer copies untimed); only the commit counts.
  row.build_seconds = time_iterations(
      state,
      [&] {
        rtcCommitScene(scene.get());
        after = g_embree_bytes;
      },
      [&] {
        scene.reset();
        scene = make_embree_scene(mesh->scene, embree_quality(s));
        before = g_embree_bytes;
      });
  const std::int64_t bytes = after - before;
  row.bytes_per_triangle = double(bytes) / double(mesh->scene.triangles.size());
  set_build_counters(state, *mesh, row);
  mesh->embree[s] = std::move(scene);
}

void bench_embree_trace(benchmark::State& state, MeshCase* mesh, Structure s, kiln::RayKind kind,
                        bool all_threads) {
  const std::vector<kiln::Ray>* rays = nullptr;
  try {
    rays = &rays_for(*mesh, kind);
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  const RTCScene scene = embree_for(*mesh, s);
  std::vector<kiln::Hit> hits(rays->size());
  const bool any_hit = is_any_hit(kind);
  auto trace_one = [&](std::size_t i) { hits[i] = embree_trace(scene, (*rays)[i], any_hit); };
  const double seconds = time_iterations(state, [&] {
    if (all_threads) {
      for_each_ray_parallel(rays->size(), trace_one);
    } else {
      for (std::size_t i = 0; i < rays->size(); ++i) trace_one(i);
    }
    benchmark::ClobberMemory();
  });
  const double mrays = double(rays->size()) / seconds * 1e-6;
  state.counters["Mrays/s"] = mrays;
  mesh->rows[s].mrays[kind_index(kind)][all_threads] = mrays;
}

// Embree and Kiln's SBVH must see the same scene: compare hit/miss on every ray (and, for closest
// hits, the primitive). Both trace with all threads; nothing here is timed.
Agreement check_agreement(MeshCase& mesh, Structure s, kiln::RayKind kind) {
  const std::vector<kiln::Ray>& rays = rays_for(mesh, kind);
  const kiln::FlatBvh& flat = bvh_for(mesh, kiln::BvhBuilder::kSpatial);
  const kiln::BvhView bvh(flat.nodes, flat.triangles, flat.prim_ids);
  const bool any_hit = is_any_hit(kind);
  std::vector<kiln::Hit> kiln_hits(rays.size()), embree_hits(rays.size());
  kiln::trace_rays(bvh, rays, kiln_hits, any_hit, 0);
  const RTCScene scene = embree_for(mesh, s);
  for_each_ray_parallel(
      rays.size(), [&](std::size_t i) { embree_hits[i] = embree_trace(scene, rays[i], any_hit); });
  Agreement a{s, kind, rays.size()};
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const bool kiln_hit = kiln_hits[i].prim != kiln::kNoHit;
    const bool embree_hit = embree_hits[i].prim != kiln::kNoHit;
    a.same_hit_or_miss += kiln_hit == embree_hit;
    a.same_prim += kiln_hits[i].prim == embree_hits[i].prim;
  }
  return a;
}
#endif  // KILN_BENCH_EMBREE

// ---------------------------------------------------------------------------------------------
// Registration.

bool is_embree(Structure s) {
  return s == Structure::kEmbreeMedium || s == Structure::kEmbreeHigh;
}

// Kiln structures that are traced (the sweep builder's tree is only built: its SAH sits between
// binned and SBVH, and tracing it would add minutes for little).
bool is_traced(Structure s) {
  return s != Structure::kSweep;
}

void register_mesh(MeshCase* mesh) {
  const int build_iterations = iterations_for(*mesh, true);
  const int trace_iterations = iterations_for(*mesh, false);
  for (Structure s : kStructures) {
    const std::string name = "build/" + mesh->label + "/" + structure_name(s);
    if (!is_embree(s)) {
      benchmark::RegisterBenchmark(name.c_str(), bench_kiln_build, mesh, s)
          ->Iterations(build_iterations)
          ->UseManualTime()
          ->Unit(benchmark::kMillisecond);
    }
#ifdef KILN_BENCH_EMBREE
    if (is_embree(s)) {
      benchmark::RegisterBenchmark(name.c_str(), bench_embree_build, mesh, s)
          ->Iterations(build_iterations)
          ->UseManualTime()
          ->Unit(benchmark::kMillisecond);
    }
#endif
  }
  for (Structure s : kStructures) {
    if (!is_traced(s)) continue;
    for (kiln::RayKind kind : kRayKinds) {
      for (bool all_threads : {false, true}) {
        const std::string name = "trace/" + mesh->label + "/" + structure_name(s) + "/" +
                                 ray_kind_name(kind) + (all_threads ? "/all-threads" : "/1-thread");
        benchmark::internal::Benchmark* b = nullptr;
        if (!is_embree(s)) {
          b = benchmark::RegisterBenchmark(name.c_str(), bench_kiln_trace, mesh, s, kind,
                                           all_threads);
        }
#ifdef KILN_BENCH_EMBREE
        if (is_embree(s)) {
          b = benchmark::RegisterBenchmark(name.c_str(), bench_embree_trace, mesh, s, kind,
                                           all_threads);
        }
#endif
        if (b) b->Iterations(trace_iterations)->UseManualTime()->Unit(benchmark::kMillisecond);
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Command line.

// "[LABEL=]@DIR[/PATTERN]" -> the matching files, sorted; a plain path -> itself.
std::optional<MeshCase> parse_mesh(const std::string& arg) {
  std::optional<kiln::bench::MeshSpec> spec = kiln::bench::parse_mesh_spec(arg);
  if (!spec) return std::nullopt;
  MeshCase mesh;
  mesh.label = std::move(spec->label);
  mesh.files = std::move(spec->files);
  return mesh;
}

using kiln::bench::parse_number_option;

// "EX,EY,EZ,TX,TY,TZ,FOV" -> a camera; nullopt when malformed.
std::optional<kiln::RayCamera> parse_camera(const std::string& text) {
  float v[7];
  const char* p = text.c_str();
  for (int i = 0; i < 7; ++i) {
    char* end = nullptr;
    v[i] = std::strtof(p, &end);
    if (end == p || (i < 6 && *end != ',') || (i == 6 && *end != 0)) return std::nullopt;
    p = end + 1;
  }
  if (!(v[6] > 0 && v[6] < 180)) return std::nullopt;
  return kiln::RayCamera{{v[0], v[1], v[2]}, {v[3], v[4], v[5]}, v[6]};
}

bool import_meshes(std::vector<MeshCase> meshes) {
  for (MeshCase& mesh : meshes) {
    const auto start = Clock::now();
    try {
      mesh.scene = kiln::import_scene(mesh.files, 0);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s\n", e.what());
      return false;
    }
    std::fprintf(stderr, "imported %s: %zu file(s), %zu triangles, %zu vertices in %.2f s\n",
                 mesh.label.c_str(), mesh.files.size(), mesh.scene.triangles.size(),
                 mesh.scene.positions.size(), seconds_since(start));
    g_meshes.push_back(std::make_unique<MeshCase>(std::move(mesh)));
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// Report.

std::string format(const char* spec, double value) {
  if (std::isnan(value)) return "–";
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, spec, value);
  return buffer;
}

std::string with_thousands(std::uint64_t n) {
  std::string digits = std::to_string(n), out;
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}

// Build seconds with three significant digits, whatever the scale.
std::string format_seconds(double s) {
  if (std::isnan(s)) return "–";
  return format(s >= 1 ? "%.2f" : s >= 0.1 ? "%.3f" : "%.4f", s);
}

double row_value(const MeshCase& mesh, Structure s, double Row::*field) {
  const auto it = mesh.rows.find(s);
  return it == mesh.rows.end() ? kNaN : it->second.*field;
}

// Kiln's build time over Embree's comparable build: binned vs MEDIUM, SBVH vs HIGH (the one
// with spatial splits).
double build_ratio(const MeshCase& mesh, Structure s) {
  const Structure reference = s == Structure::kBinned ? Structure::kEmbreeMedium
                              : s == Structure::kSbvh ? Structure::kEmbreeHigh
                                                      : s;
  if (reference == s) return kNaN;
  return row_value(mesh, s, &Row::build_seconds) / row_value(mesh, reference, &Row::build_seconds);
}

void print_main_table() {
  std::printf(
      "\n| mesh | triangles | builder | build s | Mtris/s | SAH | B/tri | build ÷ Embree |");
  for (kiln::RayKind kind : kRayKinds)
    std::printf(" %s 1T | %s %uT |", ray_kind_name(kind), ray_kind_name(kind), hardware_threads());
  std::printf("\n|---|---:|---|---:|---:|---:|---:|---:|");
  for (std::size_t i = 0; i < kRayKinds.size(); ++i) std::printf("---:|---:|");
  std::printf("\n");
  for (const auto& mesh : g_meshes) {
    const double triangles = double(mesh->scene.triangles.size());
    for (Structure s : kStructures) {
      if (!mesh->rows.count(s)) continue;
      const Row& row = mesh->rows.at(s);
      std::printf("| %s | %s | %s | %s | %s | %s | %s | %s |", mesh->label.c_str(),
                  with_thousands(mesh->scene.triangles.size()).c_str(), structure_name(s),
                  format_seconds(row.build_seconds).c_str(),
                  format("%.2f", triangles / row.build_seconds * 1e-6).c_str(),
                  format("%.1f", row.sah_cost).c_str(),
                  format("%.1f", row.bytes_per_triangle).c_str(),
                  format("%.2f×", build_ratio(*mesh, s)).c_str());
      for (std::size_t k = 0; k < kRayKinds.size(); ++k)
        std::printf(" %s | %s |", format("%.2f", row.mrays[k][0]).c_str(),
                    format("%.2f", row.mrays[k][1]).c_str());
      std::printf("\n");
    }
  }
}

#ifdef KILN_BENCH_EMBREE
double row_mrays(const MeshCase& mesh, Structure s, std::size_t kind, int threads) {
  const auto it = mesh.rows.find(s);
  return it == mesh.rows.end() ? kNaN : it->second.mrays[kind][threads];
}

void print_ratio_table() {
  std::printf(
      "\nMrays/s of Kiln's SBVH ÷ Embree HIGH on the same rays (above 1: Kiln faster):\n\n");
  std::printf("| mesh |");
  for (kiln::RayKind kind : kRayKinds)
    std::printf(" %s 1T | %s %uT |", ray_kind_name(kind), ray_kind_name(kind), hardware_threads());
  std::printf("\n|---|");
  for (std::size_t i = 0; i < kRayKinds.size(); ++i) std::printf("---:|---:|");
  std::printf("\n");
  for (const auto& mesh : g_meshes) {
    std::printf("| %s |", mesh->label.c_str());
    for (std::size_t k = 0; k < kRayKinds.size(); ++k) {
      for (int t : {0, 1}) {
        const double ratio = row_mrays(*mesh, Structure::kSbvh, k, t) /
                             row_mrays(*mesh, Structure::kEmbreeHigh, k, t);
        std::printf(" %s |", format("%.2f×", ratio).c_str());
      }
    }
    std::printf("\n");
  }
}

void print_agreement_table() {
  if (g_agreements.empty()) return;  // no Embree scene was built (--benchmark_filter)
  std::printf("\nEmbree vs Kiln SBVH, same rays (required: hit/miss agree on ≥ 99.9%%):\n\n");
  std::printf("| mesh | Embree | rays | kind | hit/miss agree | same primitive |\n");
  std::printf("|---|---|---:|---|---:|---:|\n");
  for (const auto& [mesh, a] : g_agreements) {
    const bool closest = !is_any_hit(a.kind);
    std::printf("| %s | %s | %s | %s | %.4f%% | %s |\n", mesh->label.c_str(),
                structure_name(a.embree), with_thousands(a.rays).c_str(), ray_kind_name(a.kind),
                100 * a.fraction(),
                closest ? format("%.4f%%", 100 * double(a.same_prim) / double(a.rays)).c_str()
                        : "– (any hit)");
  }
}
#endif  // KILN_BENCH_EMBREE

void print_report() {
  std::printf("\n## kiln_bench_bvh: %zu rays per kind, seed %llu, %u hardware threads\n",
              g_settings.rays, static_cast<unsigned long long>(g_settings.seed),
              hardware_threads());
  std::printf(
      "\nFastest of the timed iterations. Build: all threads (Kiln threads = 0; Embree's TBB "
      "pool). SAH in triangle tests (k-d tree: its cost over Ci). B/tri: Kiln = nodes + "
      "triangles + prim ids; Embree = net bytes allocated by "
      "rtcCommitScene (memory monitor, allocator slack included). build ÷ Embree: Kiln binned ÷ "
      "Embree MEDIUM, Kiln SBVH ÷ Embree HIGH (above 1: Kiln slower). Mrays/s: primary and diffuse "
      "= closest hit, shadow = any hit.\n");
  print_main_table();
#ifdef KILN_BENCH_EMBREE
  print_ratio_table();
  print_agreement_table();
#endif
}

// ---------------------------------------------------------------------------------------------
// Alternating comparison (--rounds): every contestant traces every ray set once per round, in a
// fixed order, so slow phases of a shared machine hit Kiln and Embree alike; the ratio of each
// round is taken before the median.

struct Contestant {
  std::string name;
  double bytes_per_triangle = kNaN;
  std::function<void(const std::vector<kiln::Ray>&, std::vector<kiln::Hit>&, bool, bool)> trace;
  std::function<kiln::Cost(const kiln::Ray&)> cost;  // Kiln: node visits and triangle tests
};

// Kiln's layouts, kept alive for the views the contestants hold.
// The arenas of the Kiln contestants, 64-byte aligned as in a blob.
using KilnArenas = std::map<std::string, kiln::AlignedBuffer>;

const kiln::AlignedBuffer& arena_copy(KilnArenas& arenas, const std::string& name,
                                      std::span<const std::byte> arena) {
  auto& buffer = arenas.emplace(name, kiln::AlignedBuffer(arena.size(), 64)).first->second;
  std::memcpy(buffer.data(), arena.data(), arena.size());
  return buffer;
}

template <class View>
Contestant kiln_contestant(std::string name, View view, double bytes_per_triangle) {
  return {std::move(name), bytes_per_triangle,
          [view](const std::vector<kiln::Ray>& rays, std::vector<kiln::Hit>& hits, bool any_hit,
                 bool all_threads) {
            if (all_threads) {
              kiln::trace_rays(view, rays, hits, any_hit, 0);
            } else {
              trace_kiln_single(view, rays, hits, any_hit);
            }
          },
          [view](const kiln::Ray& ray) {
            kiln::Cost cost;
            view.intersect_counting(ray, cost);
            return cost;
          }};
}

// Whether --only keeps some contestant whose name starts with `prefix`.
bool wanted(const std::string& prefix) {
  if (g_settings.only.empty()) return true;
  return std::any_of(g_settings.only.begin(), g_settings.only.end(),
                     [&](const std::string& n) { return n.starts_with(prefix); });
}

// The key of a --collapse variant (its tree), and the name of its contestant (with the kernel).
std::string collapse_key(const std::string& label) {
  return "sbvh w" + std::to_string(g_settings.collapse_width) + " " + label;
}
std::string collapse_name(const std::string& label) {
  return collapse_key(label) + " " +
         kiln::bvh_kernel_name(kiln::bvh_auto_kernel(g_settings.collapse_width));
}

// The --collapse variants of the SBVH's wide layout (8-wide unless --collapse-width), default
// kernel.
void add_collapse_variants(MeshCase& mesh, KilnArenas& arenas, std::vector<Contestant>& out) {
  const std::size_t triangles = mesh.scene.triangles.size();
  const std::uint32_t width = g_settings.collapse_width;
  for (const auto& [label, options] : g_settings.collapses) {
    const std::string key = collapse_key(label);
    const std::string name = collapse_name(label);
    if (!wanted(name)) continue;
    const kiln::FlatBvh& flat = sbvh_for_variant(mesh, label);
    const kiln::FlatWideBvh w = kiln::collapse_bvh(flat, width, triangles, false, nullptr, options);
    std::printf("- %s: %llu nodes, %llu packets, fill %.3f, %.1f B/tri\n", key.c_str(),
                (unsigned long long)w.stats.node_count, (unsigned long long)w.stats.packet_count,
                w.stats.packet_fill, w.stats.bytes_per_triangle);
    out.push_back(kiln_contestant(
        name, kiln::BvhWideView(width, false, arena_copy(arenas, name, w.arena).bytes(), key),
        w.stats.bytes_per_triangle));
  }
}

void add_kiln_contestants(MeshCase& mesh, KilnArenas& arenas, std::vector<Contestant>& out) {
  const std::size_t triangles = mesh.scene.triangles.size();
  for (const auto builder : {kiln::BvhBuilder::kSpatial, kiln::BvhBuilder::kBinned}) {
    const std::string b = builder == kiln::BvhBuilder::kSpatial ? "sbvh" : "bvh";
    if (!wanted(b + " ")) continue;
    const kiln::FlatBvh& flat = bvh_for(mesh, builder);
    if (wanted(b + " w2"))
      out.push_back(kiln_contestant(b + " w2",
                                    kiln::BvhView(flat.nodes, flat.triangles, flat.prim_ids),
                                    flat.stats.bytes_per_triangle));
    for (const auto& [width, quantized] :
         {std::pair{4u, false}, std::pair{8u, false}, std::pair{4u, true}, std::pair{8u, true},
          std::pair{16u, false}}) {
      const std::string key = b + " w" + std::to_string(width) + (quantized ? "q" : "");
      if (!wanted(key + " ")) continue;
      const kiln::FlatWideBvh w =
          kiln::collapse_bvh(bvh_for(mesh, builder, true), width, triangles, quantized);
      if (!quantized)
        std::printf("- %s: %llu binary nodes, %llu wide nodes, %llu packets, SAH %.3f\n",
                    key.c_str(), (unsigned long long)bvh_for(mesh, builder, true).nodes.size(),
                    (unsigned long long)w.stats.node_count,
                    (unsigned long long)w.stats.packet_count, w.stats.sah_cost);
      for (const auto kernel : {kiln::BvhKernel::kScalar, kiln::BvhKernel::kSse,
                                kiln::BvhKernel::kAvx2, kiln::BvhKernel::kAvx512}) {
        if (!kiln::bvh_kernel_supported(kernel)) continue;
        // Every kernel on the SBVH's 8-wide layout, AVX-512 and AVX2 on its 16-wide one; the
        // others with the default kernel.
        const bool sbvh = builder == kiln::BvhBuilder::kSpatial;
        const bool all_kernels = sbvh && ((width == 8 && !quantized) ||
                                          (width == 16 && (kernel == kiln::BvhKernel::kAvx512 ||
                                                           kernel == kiln::BvhKernel::kAvx2)));
        if (!all_kernels && kernel != kiln::bvh_auto_kernel(width)) continue;
        const std::string name = key + " " + kiln::bvh_kernel_name(kernel);
        if (!wanted(name)) continue;
        // Each kernel traces its own copy, so none finds the caches warmed by another's pass.
        out.push_back(kiln_contestant(
            name,
            kiln::BvhWideView(width, quantized, arena_copy(arenas, name, w.arena).bytes(), key,
                              kernel),
            w.stats.bytes_per_triangle));
      }
    }
  }
}

#ifdef KILN_BENCH_EMBREE
void add_embree_contestants(MeshCase& mesh, std::vector<std::shared_ptr<EmbreeScene>>& scenes,
                            std::vector<Contestant>& out) {
  struct Kind {
    const char* name;
    RTCBuildQuality quality;
    RTCSceneFlags flags;
  };
  for (const Kind k : {Kind{"embree medium", RTC_BUILD_QUALITY_MEDIUM, RTC_SCENE_FLAG_NONE},
                       Kind{"embree high", RTC_BUILD_QUALITY_HIGH, RTC_SCENE_FLAG_NONE},
                       Kind{"embree high robust", RTC_BUILD_QUALITY_HIGH, RTC_SCENE_FLAG_ROBUST}}) {
    if (!wanted(k.name)) continue;
    auto scene = std::make_shared<EmbreeScene>(make_embree_scene(mesh.scene, k.quality, k.flags));
    const std::int64_t before = g_embree_bytes;
    rtcCommitScene(scene->get());
    const double bytes = double(g_embree_bytes - before) / double(mesh.scene.triangles.size());
    scenes.push_back(scene);
    const RTCScene s = scene->get();
    out.push_back({k.name,
                   bytes,
                   [s](const std::vector<kiln::Ray>& rays, std::vector<kiln::Hit>& hits,
                       bool any_hit, bool all_threads) {
                     auto one = [&](std::size_t i) { hits[i] = embree_trace(s, rays[i], any_hit); };
                     if (all_threads) {
                       for_each_ray_parallel(rays.size(), one);
                     } else {
                       for (std::size_t i = 0; i < rays.size(); ++i) one(i);
                     }
                   },
                   {}});  // no cost counter for Embree
  }
}
#endif

double thread_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return double(t.tv_sec) + double(t.tv_nsec) * 1e-9;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  if (v.empty()) return kNaN;
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

// Seconds per pass: [contestant][round].
using Times = std::vector<std::vector<double>>;

Times run_rounds(const std::vector<Contestant>& contestants, const std::vector<kiln::Ray>& rays,
                 bool any_hit, bool all_threads) {
  Times times(contestants.size());
  std::vector<kiln::Hit> hits(rays.size());
  for (int round = 0; round < g_settings.rounds; ++round)
    for (std::size_t i = 0; i < contestants.size(); ++i) {
      // Odd rounds in reverse order: no contestant always follows the same one.
      const std::size_t c = round % 2 ? contestants.size() - 1 - i : i;
      // One thread: its CPU time, which time slices lost to other work on a shared machine do
      // not inflate; all threads: wall time (throughput).
      const double cpu_start = thread_cpu_seconds();
      const auto start = Clock::now();
      contestants[c].trace(rays, hits, any_hit, all_threads);
      benchmark::ClobberMemory();
      times[c].push_back(all_threads ? seconds_since(start) : thread_cpu_seconds() - cpu_start);
    }
  return times;
}

// Median over rounds of (reference's time ÷ contestant's time): above 1, the contestant is faster.
double median_ratio(const Times& t, std::size_t contestant, std::size_t reference) {
  std::vector<double> ratios;
  for (std::size_t r = 0; r < t[contestant].size(); ++r)
    ratios.push_back(t[reference][r] / t[contestant][r]);
  return median(ratios);
}

// Node visits and triangle tests per closest-hit ray of one kind (untimed, counting kernels).
void print_work(const MeshCase& mesh, const std::vector<Contestant>& contestants,
                kiln::RayKind kind, const char* label) {
  std::printf(
      "\nWork per closest-hit %s ray (untimed): node visits + triangle tests (wide: "
      "tests = 4 per packet):\n\n",
      label);
  const auto& rays =
      g_meshes.empty() ? std::vector<kiln::Ray>{} : const_cast<MeshCase&>(mesh).rays[kind];
  for (const auto& c : contestants) {
    if (!c.cost || c.name.find("scalar") != std::string::npos) continue;
    double nodes = 0, tests = 0;
    for (const auto& ray : rays) {
      const kiln::Cost k = c.cost(ray);
      nodes += k.nodes, tests += k.tests;
    }
    const double n = double(std::max<std::size_t>(rays.size(), 1));
    std::printf("- %s: %.1f nodes, %.1f tests\n", c.name.c_str(), nodes / n, tests / n);
  }
}

void print_alternating(const MeshCase& mesh, const std::vector<Contestant>& contestants,
                       const std::vector<std::array<Times, 2>>& times, std::size_t rays) {
  std::printf("\n### %s (%s triangles%s): median Mrays/s of %d rounds\n\n", mesh.label.c_str(),
              with_thousands(mesh.scene.triangles.size()).c_str(),
              mesh.camera ? ", camera inside" : "", g_settings.rounds);
  std::printf(
      "| layout | B/tri | primary 1T | primary %uT | diffuse 1T | diffuse %uT | shadow 1T | shadow "
      "%uT |\n",
      hardware_threads(), hardware_threads(), hardware_threads());
  std::printf("|---|---:|---:|---:|---:|---:|---:|---:|\n");
  for (std::size_t c = 0; c < contestants.size(); ++c) {
    std::printf("| %s | %s |", contestants[c].name.c_str(),
                format("%.1f", contestants[c].bytes_per_triangle).c_str());
    for (std::size_t k = 0; k < kRayKinds.size(); ++k)
      for (int t : {0, 1})
        std::printf(" %s |", format("%.2f", double(rays) / median(times[k][t][c]) * 1e-6).c_str());
    std::printf("\n");
  }
  print_work(mesh, contestants, kiln::RayKind::kPrimary, "primary");
  print_work(mesh, contestants, kiln::RayKind::kDiffuse, "diffuse");
  auto find = [&](const std::string& name) {
    for (std::size_t c = 0; c < contestants.size(); ++c)
      if (contestants[c].name == name) return c;
    return contestants.size();
  };
  const std::string auto_kernel = kiln::bvh_kernel_name(kiln::bvh_auto_kernel());
  std::printf("\nMedian of per-round ratios, Kiln ÷ Embree (above 1: Kiln faster):\n\n");
  std::printf(
      "| Kiln | Embree | primary 1T | primary %uT | diffuse 1T | diffuse %uT | shadow 1T | shadow "
      "%uT |\n",
      hardware_threads(), hardware_threads(), hardware_threads());
  std::printf("|---|---|---:|---:|---:|---:|---:|---:|\n");
  std::vector<std::string> kiln_names = {"sbvh w16 avx512", "sbvh w16 avx2"};
  for (const char* layout : {"sbvh w8", "sbvh w8q", "bvh w8", "bvh w8q", "sbvh w4"})
    kiln_names.push_back(std::string(layout) + " " + auto_kernel);
  kiln_names.push_back(std::string("bvh w16 ") + kiln::bvh_kernel_name(kiln::bvh_auto_kernel(16)));
  kiln_names.push_back("sbvh w2");
  for (const auto& variant : g_settings.collapses)
    kiln_names.push_back(collapse_name(variant.first));
  // Against Embree, against Kiln's default layout (for the --collapse variants), and against the
  // avx512 slot (which a development build can fill with another AVX2 kernel: new ÷ old).
  const std::string kiln_default = "sbvh w8 " + auto_kernel;
  for (const std::string& kiln_name : kiln_names)
    for (const std::string& embree_name :
         {std::string("embree medium"), std::string("embree high"),
          std::string("embree high robust"), kiln_default, std::string("sbvh w8 avx512"),
          std::string("sbvh w16 avx512")}) {
      const std::string& name = kiln_name;
      const std::size_t a = find(name), b = find(embree_name);
      if (a == contestants.size() || b == contestants.size() || a == b) continue;
      std::printf("| %s | %s |", name.c_str(), embree_name.c_str());
      for (std::size_t k = 0; k < kRayKinds.size(); ++k)
        for (int t : {0, 1})
          std::printf(" %s |", format("%.2f×", median_ratio(times[k][t], a, b)).c_str());
      std::printf("\n");
    }
}

void run_alternating(MeshCase& mesh) {
  std::vector<Contestant> contestants;
  KilnArenas arenas;
  add_kiln_contestants(mesh, arenas, contestants);
  add_collapse_variants(mesh, arenas, contestants);
#ifdef KILN_BENCH_EMBREE
  std::vector<std::shared_ptr<EmbreeScene>> scenes;
  add_embree_contestants(mesh, scenes, contestants);
#endif
  std::vector<std::array<Times, 2>> times(kRayKinds.size());
  std::size_t count = 0;
  for (std::size_t k = 0; k < kRayKinds.size(); ++k) {
    const auto& rays = rays_for(mesh, kRayKinds[k]);
    count = rays.size();
    for (int t : {0, 1})
      times[k][t] = t == 1 && g_settings.one_thread
                        ? Times(contestants.size(), std::vector<double>(1, kNaN))
                        : run_rounds(contestants, rays, is_any_hit(kRayKinds[k]), t == 1);
  }
  print_alternating(mesh, contestants, times, count);
}

// LABEL:NODE:PACKET:MAXREFS[:LEAF[:ORDER]] or LABEL:greedy; ORDER 0 tree, 1 largest area,
// 2 occlusion (the default).
std::optional<std::pair<std::string, kiln::WideCollapseOptions>> parse_collapse(
    const std::string& text) {
  const std::size_t colon = text.find(':');
  if (colon == 0 || colon == std::string::npos) return std::nullopt;
  kiln::WideCollapseOptions o;
  const std::string rest = text.substr(colon + 1);
  if (rest == "greedy") {
    o.greedy = true;
    o.order = kiln::WideSlotOrder::kTree;  // the collapse as it was
  } else {
    unsigned max_refs = 0;
    int order = int(o.order);
    if (std::sscanf(rest.c_str(), "%lf:%lf:%u:%lf:%d", &o.node_cost, &o.packet_cost, &max_refs,
                    &o.leaf_cost, &order) < 3 ||
        order < 0 || order > 2)
      return std::nullopt;
    o.max_leaf_refs = max_refs;
    o.order = kiln::WideSlotOrder(order);
  }
  return std::pair{text.substr(0, colon), o};
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);  // removes the --benchmark_* flags
  std::vector<MeshCase> meshes;
  std::optional<kiln::RayCamera> camera;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    try {
      if (parse_number_option(arg, "rays", g_settings.rays) ||
          parse_number_option(arg, "seed", g_settings.seed) ||
          parse_number_option(arg, "iterations", g_settings.iterations) ||
          parse_number_option(arg, "rounds", g_settings.rounds) ||
          parse_number_option(arg, "collapse-width", g_settings.collapse_width))
        continue;
    } catch (const std::exception&) {
      std::fprintf(stderr, "bad number in '%s'\n", arg.c_str());
      return 2;
    }
    if (arg.starts_with("--only=")) {
      for (std::size_t at = 7; at <= arg.size();) {
        const std::size_t end = std::min(arg.find(',', at), arg.size());
        g_settings.only.push_back(arg.substr(at, end - at));
        at = end + 1;
      }
      continue;
    }
    if (arg == "--one-thread") {
      g_settings.one_thread = true;
      continue;
    }
    if (arg.starts_with("--sbvh-build=")) {
      // LABEL:TRAV:ISECT:MAXLEAF[:ALPHA]: the --collapse variant LABEL collapses an SBVH built
      // with these costs, leaf size and spatial-split threshold.
      const std::string text = arg.substr(13);
      const std::size_t colon = text.find(':');
      kiln::BvhBuildOptions o;
      o.builder = kiln::BvhBuilder::kSpatial;
      o.threads = 0;
      o.leaf_packet = kiln::format::kBvhPacketSize;  // as `kiln build` builds for w4 / w8
      if (colon == std::string::npos ||
          std::sscanf(text.c_str() + colon + 1, "%f:%f:%u:%f", &o.traversal_cost,
                      &o.intersection_cost, &o.max_leaf_size, &o.sbvh_alpha) < 3) {
        std::fprintf(stderr, "bad sbvh build in '%s' (LABEL:TRAV:ISECT:MAXLEAF[:ALPHA])\n",
                     arg.c_str());
        return 2;
      }
      g_settings.sbvh_builds[text.substr(0, colon)] = o;
      continue;
    }
    if (arg.starts_with("--collapse=")) {
      const std::optional<std::pair<std::string, kiln::WideCollapseOptions>> c =
          parse_collapse(arg.substr(11));
      if (!c) {
        std::fprintf(
            stderr,
            "bad collapse in '%s' (LABEL:NODE:PACKET:MAXREFS[:LEAF[:ORDER 0-2]] or LABEL:greedy)\n",
            arg.c_str());
        return 2;
      }
      g_settings.collapses.push_back(*c);
      continue;
    }
    if (arg.starts_with("--camera=")) {
      camera = parse_camera(arg.substr(9));
      if (!camera && arg != "--camera=none") {
        std::fprintf(stderr, "bad camera in '%s' (EX,EY,EZ,TX,TY,TZ,FOV)\n", arg.c_str());
        return 2;
      }
      continue;
    }
    if (arg.starts_with("--")) {
      std::fprintf(stderr, "unknown option '%s'\n", arg.c_str());
      return 2;
    }
    std::optional<MeshCase> mesh = parse_mesh(arg);
    if (!mesh) return 2;
    mesh->camera = camera;
    meshes.push_back(std::move(*mesh));
  }
  if (meshes.empty()) {
    std::fprintf(stderr,
                 "usage: kiln_bench_bvh [--rays=N] [--seed=N] [--iterations=N] MESH... "
                 "[benchmark flags]\n  MESH: a file, or [LABEL=]@DIR[/PATTERN] (default *.obj) "
                 "for every matching file in DIR as one scene\n");
    return 2;
  }
  if (!import_meshes(std::move(meshes))) return 1;
  if (g_settings.rounds > 0) {
    std::printf(
        "## kiln_bench_bvh --rounds=%d: %zu rays per kind, seed %llu, %u threads, "
        "default kernel %s\n",
        g_settings.rounds, g_settings.rays, (unsigned long long)g_settings.seed, hardware_threads(),
        kiln::bvh_kernel_name(kiln::bvh_auto_kernel()));
    for (const auto& mesh : g_meshes) run_alternating(*mesh);
    return 0;
  }
  for (const auto& mesh : g_meshes) register_mesh(mesh.get());

  benchmark::RunSpecifiedBenchmarks();

  bool agree = true;
#ifdef KILN_BENCH_EMBREE
  for (const auto& mesh : g_meshes) {
    for (Structure s : {Structure::kEmbreeMedium, Structure::kEmbreeHigh}) {
      if (!mesh->embree.count(s)) continue;  // filtered out
      for (kiln::RayKind kind : kRayKinds) {
        if (!mesh->rays.count(kind)) continue;
        const Agreement a = check_agreement(*mesh, s, kind);
        agree = agree && a.fraction() >= 0.999;
        g_agreements.emplace_back(mesh.get(), a);
      }
    }
  }
#endif
  print_report();
  benchmark::Shutdown();
  if (!agree) std::fprintf(stderr, "Embree and Kiln disagree on more than 0.1%% of some ray set\n");
  return agree ? 0 : 1;
}
