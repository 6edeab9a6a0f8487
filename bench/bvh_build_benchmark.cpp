// Build time of Kiln's BVH builders against Embree 3's, alternating in one process (issue 16,
// builders part). Each round builds every contestant once, in a fixed order, on one thread and
// then on all threads; the report gives medians over rounds and the median of per-round ratios,
// so that load from other processes on a shared machine hits both sides alike.
//
// Usage: kiln_bench_bvh_build [--rounds=N] [--only=binned|sbvh] [--sbvh-alpha=X]
//                             [--leaf-packet=N] [--width=4|8|16] [--each] [--keep-memory]
//                             [--warm-free=MB] MESH...
//   MESH  a file import_scene reads, or [LABEL=]@DIR[/PATTERN] (bench_args.hpp)
//
// One thread is timed by the process's CPU time (CLOCK_PROCESS_CPUTIME_ID: Embree may build on a
// TBB worker rather than the calling thread; time slices lost to other processes do not count),
// all threads by wall time. Kiln: build_bvh (binary tree, no leaf triangle copy, as the wide
// layout uses it) and, timed apart, its collapse to --width children (default 16) with triangle
// packets, the arena `kiln build` stores by default. Embree: rtcCommitScene on a fresh scene;
// Embree 3.13 builds a BVH8<triangle4> there on an AVX machine (its verbose log says so), leaf data
// included, so the like-for-like ratio is Kiln's build plus collapse ("+ wN"); the binary-only
// ratio is kept for comparison with earlier figures. The collapse columns are its medians over the
// rounds (1T CPU, all threads wall). Peak memory: the largest net heap growth during the build
// (Kiln: operator new, counted here; Embree: its memory monitor), per input triangle.
#include <malloc.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <time.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <new>
#include <string>
#include <thread>
#include <vector>

#include "bench_args.hpp"
#include "kiln/compiler/build.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/compiler/bvh_collapse.hpp"
#include "kiln/formats/bvh_wide.hpp"

#ifdef KILN_BENCH_EMBREE
#include <embree3/rtcore.h>
#endif

// ---------------------------------------------------------------------------------------------
// Heap accounting for Kiln's builds: every operator new of this process, net and peak.

namespace {
std::atomic<std::int64_t> g_heap_now{0}, g_heap_peak{0};

void note_alloc(std::int64_t bytes) {
  const std::int64_t now = g_heap_now.fetch_add(bytes) + bytes;
  std::int64_t peak = g_heap_peak.load();
  while (now > peak && !g_heap_peak.compare_exchange_weak(peak, now)) {
  }
}
}  // namespace

// GCC 12 takes malloc/free inside a replaced operator new/delete for a mismatch.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"

void* operator new(std::size_t size) {
  void* p = std::malloc(size ? size : 1);
  if (!p) throw std::bad_alloc();
  note_alloc(std::int64_t(malloc_usable_size(p)));
  return p;
}
void* operator new[](std::size_t size) {
  return operator new(size);
}
void operator delete(void* p) noexcept {
  if (!p) return;
  g_heap_now -= std::int64_t(malloc_usable_size(p));
  std::free(p);
}
void operator delete[](void* p) noexcept {
  operator delete(p);
}
void operator delete(void* p, std::size_t) noexcept {
  operator delete(p);
}
void operator delete[](void* p, std::size_t) noexcept {
  operator delete(p);
}

namespace {

double cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

double wall_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

struct Sample {
  double seconds = 0, peak_bytes = 0;
  double system_seconds = 0;  // the kernel's share (page faults on fresh memory), for --each
};

// The process's system CPU time (the kernel's, on its behalf: mostly page faults here).
double system_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_stime.tv_sec) + 1e-6 * double(u.ru_stime.tv_usec);
}

// --warm-free=MB: before every timed build, Kiln's and Embree's alike, map MB, write every page
// and unmap it again (untimed), so that the kernel's free lists start with that much memory just
// used. Diagnosis of the free page reporting of VMs like this one (docs/BENCHMARKS.md): a block
// free for about 2 s goes back to the host, and its next user pays the host's faults, so a
// builder's time would otherwise depend on how much memory the builder before it freed.
std::size_t g_warm_free = 0;

void warm_free_memory() {
  if (g_warm_free == 0) return;
  void* p = mmap(nullptr, g_warm_free, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) return;
  madvise(p, g_warm_free, MADV_HUGEPAGE);  // as both builders' large blocks
  for (std::size_t i = 0; i < g_warm_free; i += 4096) static_cast<volatile char*>(p)[i] = 1;
  munmap(p, g_warm_free);
}

// One timed build; `threads` 1 -> process CPU time, otherwise wall time.
template <class Build>
Sample timed(unsigned threads, Build&& build) {
  warm_free_memory();
  const double c0 = cpu_seconds(), w0 = wall_seconds(), k0 = system_seconds();
  const double peak = build();
  const double s = threads == 1 ? cpu_seconds() - c0 : wall_seconds() - w0;
  return {s, peak, system_seconds() - k0};
}

float g_sbvh_alpha = kiln::BvhBuildOptions{}.sbvh_alpha;  // --sbvh-alpha=X
// --leaf-packet=N: leaves priced per packet of N, as `kiln build` builds for the 8-wide layout
// (4); 0 prices each reference (the binary layout's tree).
std::uint32_t g_leaf_packet = kiln::format::kBvhPacketSize;
// --width=W: the wide layout the collapse writes (16: `kiln build`'s default with float boxes).
std::uint32_t g_width = 16;

struct KilnResult {
  kiln::BvhStatistics stats;
  double collapse_seconds = 0;
  double collapse_system_seconds = 0;
  double wide_sah = 0;  // the wide tree's SAH cost (the collapse's model)
};

KilnResult kiln_build(const kiln::Scene& scene, kiln::BvhBuilder builder, unsigned threads,
                      Sample& sample) {
  kiln::BvhBuildOptions o;
  o.builder = builder;
  o.threads = threads;
  o.leaf_triangles = false;
  o.sbvh_alpha = g_sbvh_alpha;
  o.leaf_packet = g_leaf_packet;
  KilnResult out;
  kiln::FlatBvh flat;
  sample = timed(threads, [&] {
    const std::int64_t base = g_heap_now.load();
    g_heap_peak = base;
    flat = kiln::build_bvh(scene, o);
    return double(g_heap_peak.load() - base);
  });
  out.stats = flat.stats;
  const double c0 = threads == 1 ? cpu_seconds() : wall_seconds(), k0 = system_seconds();
  kiln::WideCollapseOptions c;
  c.threads = threads;
  c.index_tree = false;     // as kiln build: the arena alone
  c.scratch = &flat.spare;  // as kiln build: the build's finished references as scratch
  const kiln::FlatWideBvh wide =
      kiln::collapse_bvh(flat, g_width, scene.triangles.size(), false, &scene, c);
  out.collapse_seconds = (threads == 1 ? cpu_seconds() : wall_seconds()) - c0;
  out.collapse_system_seconds = system_seconds() - k0;
  out.wide_sah = wide.stats.sah_cost;
  return out;
}

#ifdef KILN_BENCH_EMBREE
std::atomic<std::int64_t> g_embree_now{0}, g_embree_peak{0};

bool track_embree(void*, ssize_t bytes, bool) {
  const std::int64_t now = g_embree_now.fetch_add(bytes) + bytes;
  std::int64_t peak = g_embree_peak.load();
  while (now > peak && !g_embree_peak.compare_exchange_weak(peak, now)) {
  }
  return true;
}

// A fresh scene over copies of the mesh (untimed), committed (timed).
Sample embree_build(RTCDevice device, const kiln::Scene& scene, RTCBuildQuality quality,
                    unsigned threads, double& kept_bytes) {
  RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* v = static_cast<kiln::format::Float3*>(
      rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                              sizeof(kiln::format::Float3), scene.positions.size()));
  std::copy(scene.positions.begin(), scene.positions.end(), v);
  auto* t = static_cast<kiln::format::Triangle*>(
      rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                              sizeof(kiln::format::Triangle), scene.triangles.size()));
  std::copy(scene.triangles.begin(), scene.triangles.end(), t);
  rtcSetGeometryBuildQuality(g, quality);
  rtcCommitGeometry(g);
  RTCScene s = rtcNewScene(device);
  rtcSetSceneBuildQuality(s, quality);
  rtcAttachGeometry(s, g);
  rtcReleaseGeometry(g);
  const std::int64_t base = g_embree_now.load();
  const Sample sample = timed(threads, [&] {
    g_embree_peak = base;
    rtcCommitScene(s);
    return double(g_embree_peak.load() - base);
  });
  kept_bytes = double(g_embree_now.load() - base);
  rtcReleaseScene(s);
  return sample;
}

RTCDevice embree_device(unsigned threads) {
  const std::string config = threads == 1 ? "threads=1" : "";
  RTCDevice d = rtcNewDevice(config.c_str());
  if (!d) {
    std::fprintf(stderr, "rtcNewDevice failed\n");
    std::exit(1);
  }
  rtcSetDeviceMemoryMonitorFunction(d, track_embree, nullptr);
  return d;
}
#endif

struct Row {
  std::vector<double> seconds, peak, ratio;
  std::vector<double> ratio_total;  // (build + collapse to --width) / Embree, per round
  std::vector<double> collapse;     // the collapse to --width, per round
  double kept = 0;
  KilnResult kiln;
};

struct Mesh {
  std::string label;
  kiln::Scene scene;
  std::map<std::string, Row> rows[2];  // [0: one thread, 1: all threads]
};

std::string g_only;   // --only=binned|sbvh: one builder and its Embree counterpart
bool g_each = false;  // --each: every round's times on stderr, as they come

void run_rounds(Mesh& m, int rounds, unsigned threads, int t) {
#ifdef KILN_BENCH_EMBREE
  // Devices apart per thread count: TBB's global limit is the smallest of the live devices'.
  RTCDevice device = embree_device(threads);
#endif
  auto& rows = m.rows[t];
  for (int r = 0; r < rounds; ++r) {
    for (const auto& [name, builder] : {std::pair{"binned", kiln::BvhBuilder::kBinned},
                                        std::pair{"sbvh", kiln::BvhBuilder::kSpatial}}) {
      if (!g_only.empty() && g_only != name) continue;
      Sample s;
      rows[name].kiln = kiln_build(m.scene, builder, threads, s);
      rows[name].seconds.push_back(s.seconds);
      rows[name].peak.push_back(s.peak_bytes);
      rows[name].collapse.push_back(rows[name].kiln.collapse_seconds);
#ifdef KILN_BENCH_EMBREE
      const bool high = builder == kiln::BvhBuilder::kSpatial;
      const char* ename = high ? "embree-high" : "embree-medium";
      Row& e = rows[ename];
      const Sample es =
          embree_build(device, m.scene, high ? RTC_BUILD_QUALITY_HIGH : RTC_BUILD_QUALITY_MEDIUM,
                       threads, e.kept);
      e.seconds.push_back(es.seconds);
      e.peak.push_back(es.peak_bytes);
      rows[name].ratio.push_back(s.seconds / es.seconds);
      rows[name].ratio_total.push_back((s.seconds + rows[name].kiln.collapse_seconds) / es.seconds);
      if (g_each)
        std::fprintf(stderr,
                     "%s %uT round %d: %s %.4f (system %.4f) + collapse %.4f (system %.4f) s, "
                     "%s %.4f (system %.4f) s\n",
                     m.label.c_str(), threads, r + 1, name, s.seconds, s.system_seconds,
                     rows[name].kiln.collapse_seconds, rows[name].kiln.collapse_system_seconds,
                     ename, es.seconds, es.system_seconds);
#endif
    }
  }
#ifdef KILN_BENCH_EMBREE
  rtcReleaseDevice(device);
#endif
}

void report(const Mesh& m, unsigned hw) {
  const double tris = double(m.scene.triangles.size());
  std::printf("\n### %s (%zu triangles)\n\n", m.label.c_str(), m.scene.triangles.size());
  std::printf(
      "| builder | 1T s | %uT s | Mtris/s 1T | Mtris/s %uT | ÷ Embree 1T | ÷ Embree %uT | + w%u ÷ "
      "Embree 1T | + w%u ÷ Embree %uT | SAH | w%u SAH | nodes | peak B/tri | collapse w%u 1T s "
      "| collapse w%u %uT s |\n|---|"
      "---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
      hw, hw, hw, g_width, g_width, hw, g_width, g_width, g_width, hw);
  for (const auto& [name, row1] : m.rows[0]) {
    const Row& row2 = m.rows[1].at(name);
    const double s1 = median(row1.seconds), s2 = median(row2.seconds);
    const bool kiln = !row1.ratio.empty() || name == "binned" || name == "sbvh";
    std::printf("| %s | %.4f | %.4f | %.2f | %.2f | ", name.c_str(), s1, s2, tris / s1 * 1e-6,
                tris / s2 * 1e-6);
    if (!row1.ratio.empty())
      std::printf("%.2f× | %.2f× | %.2f× | %.2f× | ", median(row1.ratio), median(row2.ratio),
                  median(row1.ratio_total), median(row2.ratio_total));
    else
      std::printf("– | – | – | – | ");
    if (kiln)
      std::printf("%.3f | %.3f | %llu | %.1f | %.4f | %.4f |\n", row1.kiln.stats.sah_cost,
                  row1.kiln.wide_sah, (unsigned long long)row1.kiln.stats.node_count,
                  median(row1.peak) / tris, median(row1.collapse), median(row2.collapse));
    else
      std::printf("– | – | – | %.1f (kept %.1f) | – | – |\n", median(row1.peak) / tris,
                  row1.kept / tris);
  }
}

}  // namespace

int main(int argc, char** argv) {
  int rounds = 5;
  bool keep_memory = false;
  std::vector<Mesh> meshes;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::printf(
          "usage: %s [--rounds=N] [--only=binned|sbvh] [--sbvh-alpha=X] [--leaf-packet=N]\n"
          "       [--width=4|8|16] [--each] [--keep-memory] [--warm-free=MB] MESH...\n"
          "Build time of Kiln's BVH builders (binary build, then the collapse to --width) against\n"
          "Embree 3's, alternating in one process, 1 thread and all threads; medians over rounds\n"
          "and the median of per-round ratios. MESH: a file, or [LABEL=]@DIR[/PATTERN].\n",
          argv[0]);
      return 0;
    }
    if (kiln::bench::parse_number_option(arg, "rounds", rounds)) continue;
    if (arg.starts_with("--leaf-packet=")) {
      g_leaf_packet = std::uint32_t(std::stoul(arg.substr(14)));
      continue;
    }
    if (arg.starts_with("--sbvh-alpha=")) {
      g_sbvh_alpha = std::stof(arg.substr(13));
      continue;
    }
    if (arg.starts_with("--width=")) {
      g_width = std::uint32_t(std::stoul(arg.substr(8)));
      if (g_width != 4 && g_width != 8 && g_width != 16) {
        std::fprintf(stderr, "--width: 4, 8 or 16\n");
        return 1;
      }
      continue;
    }
    if (arg.starts_with("--warm-free=")) {
      g_warm_free = std::size_t(std::stoul(arg.substr(12))) << 20;
      continue;
    }
    if (arg == "--keep-memory") {
      keep_memory = true;
      continue;
    }
    if (arg == "--each") {
      g_each = true;
      continue;
    }
    if (arg.starts_with("--only=")) {
      g_only = arg.substr(7);
      continue;
    }
    const auto spec = kiln::bench::parse_mesh_spec(arg);
    if (!spec) return 1;
    Mesh m;
    m.label = spec->label;
    try {
      m.scene = kiln::import_scene(spec->files, 0);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s\n", e.what());
      return 1;
    }
    meshes.push_back(std::move(m));
  }
  if (meshes.empty() || rounds < 1) {
    std::fprintf(stderr,
                 "usage: kiln_bench_bvh_build [--rounds=N] [--each] [--keep-memory] "
                 "[--warm-free=MB] MESH...\n");
    return 1;
  }
  if (keep_memory) {
    // Opt-in, for diagnosis only: freed blocks stay in the process between rounds (by default
    // glibc maps blocks over its dynamic threshold anew and trims the heap's top, so a round
    // touches fresh pages again). It favours Kiln: Embree maps its large blocks itself, fresh
    // every build either way.
    mallopt(M_MMAP_THRESHOLD, 32 << 20);  // glibc's largest
    mallopt(M_TRIM_THRESHOLD, std::numeric_limits<int>::max());
  }
  const unsigned hw = std::max(1u, std::thread::hardware_concurrency());
  std::printf("## kiln_bench_bvh_build: %d rounds, medians; 1T = process CPU time, %uT = wall\n",
              rounds, hw);
  for (Mesh& m : meshes) {
    run_rounds(m, rounds, 1, 0);
    run_rounds(m, rounds, hw, 1);
    report(m, hw);
    std::fflush(stdout);
  }
  return 0;
}
