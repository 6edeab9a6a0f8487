// The `kiln` command line: build, dump, verify.
#include <CLI/CLI.hpp>

#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/build_job.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/formats/voxel_dag.hpp"
#include "kiln/runtime/atomic_file.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/parallel.hpp"
#include "kiln/tools/inspect.hpp"
#include "kiln/tools/query_command.hpp"
#include "kiln/tools/render_command.hpp"
#include "kiln/tools/trace_command.hpp"
#include "progress.hpp"

namespace {

constexpr unsigned kMaxThreads = 1024;

struct BuildArgs {
  std::vector<std::string> inputs;
  std::string output;
  std::string depfile;
  std::string cache_dir;
  bool compress = false;
  int level = 9;
  unsigned threads = 0;
  bool stats = false;
  std::vector<std::string> accels;
  kiln::BvhBuildOptions bvh;
  kiln::KdTreeBuildOptions kdtree;
  kiln::PointTreeBuildOptions points;
  kiln::VoxelizeOptions voxels;
  double contour_error = kiln::EsvoBuildOptions{}.contour_error;
  bool no_contours = false;
  std::string bvh_builder = "binned";
  std::string points_split = "sliding-midpoint";
};

int run_build(const BuildArgs& args) {
  namespace fs = std::filesystem;
  std::error_code ec;
  for (const auto& input : args.inputs)
    for (const auto& out : {args.output, args.depfile})
      if (!out.empty() && fs::exists(out, ec) && fs::equivalent(input, out, ec)) {
        std::cerr << "kiln build: output " << out << " is also an input\n";
        return 2;
      }
  if (!args.depfile.empty() &&
      (args.depfile == args.output ||
       (fs::exists(args.output, ec) && fs::equivalent(args.depfile, args.output, ec)))) {
    std::cerr << "kiln build: --depfile names the output blob\n";
    return 2;
  }
  for (const auto& kind : args.accels)
    if (kind == "esvo") try {
        kiln::EsvoBuildOptions esvo;
        esvo.contour_error = args.contour_error;
        kiln::esvo_error_bound(esvo);
      } catch (const std::invalid_argument& e) {
        std::cerr << "kiln build: " << e.what() << "\n";
        return 1;
      }
  for (const auto& kind : args.accels)
    if (kind == "dag" || kind == "esvo") {
      const std::uint32_t n = args.voxels.resolution;
      if (!kiln::format::is_valid_dag_resolution(n)) {
        std::cerr << "kiln build: --resolution " << n << " must be a power of two in "
                  << kiln::format::kDagMinResolution << ".." << kiln::format::kDagMaxResolution
                  << "\n";
        return 1;
      }
    }
  kiln::BuildOptions options;
  options.inputs = args.inputs;
  for (const auto& kind : args.accels) {
    for (const auto& request : options.accels)
      if (request.kind == kind) {
        std::cerr << "kiln build: --accel " << kind << " given twice\n";
        return 2;
      }
    kiln::AccelRequest request{kind, args.bvh, args.kdtree, args.points, args.voxels};
    request.esvo.resolution = args.voxels.resolution;
    request.esvo.contours = !args.no_contours;
    request.esvo.contour_error = args.contour_error;
    request.points.split = args.points_split == "median" ? kiln::PointSplitRule::kMedian
                                                         : kiln::PointSplitRule::kSlidingMidpoint;
    request.bvh.builder = kind == "sbvh"                ? kiln::BvhBuilder::kSpatial
                          : args.bvh_builder == "sweep" ? kiln::BvhBuilder::kSweep
                                                        : kiln::BvhBuilder::kBinned;
    options.accels.push_back(request);
  }
  options.compression = {args.compress, args.level};
  options.threads = args.threads;
  const auto start = std::chrono::steady_clock::now();
  kiln::BuildJobReport job;
  try {
    kiln::TerminalProgress progress;
    job = kiln::run_build_job({options, args.output, args.depfile, args.cache_dir},
                              [&](std::string_view stage, std::uint64_t done, std::uint64_t total) {
                                progress.update(stage, done, total);
                              });
  } catch (const kiln::ImportError& e) {
    std::cerr << "kiln build: " << e.what() << "\n";
    return 1;
  } catch (const std::bad_alloc&) {
    std::cerr << "kiln build: out of memory\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "kiln build: " << e.what() << "\n";
    return 1;
  }
  for (const auto& warning : job.warnings) std::cerr << "kiln build: warning: " << warning << "\n";
  if (job.cache_hit) std::cerr << "kiln build: cache hit " << job.cache_key << "\n";
  if (args.stats && !job.cache_key.empty() && !job.cache_hit)
    std::cerr << "kiln build: cache miss " << job.cache_key << "\n";
  const auto& reports = job.accels;
  if (args.stats) {
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const auto blob = kiln::Blob::open_file(args.output);
    const auto* scene = blob.manifest().scene();
    std::fprintf(
        stderr,
        "kiln build: %s: %llu triangles, %llu vertices, %llu bytes in %.3f s (%u threads)\n",
        args.output.c_str(), (unsigned long long)scene->triangle_count(),
        (unsigned long long)scene->vertex_count(), (unsigned long long)blob.header().file_size,
        seconds, kiln::resolve_thread_count(args.threads));
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    std::fprintf(stderr, "kiln build: peak memory %.1f MiB\n", double(usage.ru_maxrss) / 1024.0);
    for (const auto& r : reports) {
      const bool points = !kiln::needs_triangles(r.kind);
      const double count = double(points ? scene->vertex_count() : scene->triangle_count());
      std::fprintf(stderr, "kiln build: %s: built in %.3f s (%.2f %s/s), %s\n", r.kind.c_str(),
                   r.build_seconds, count / r.build_seconds * 1e-6, points ? "Mpoints" : "Mtris",
                   r.summary.c_str());
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  kiln::install_temp_file_cleanup_on_signals();
  CLI::App app{"Kiln: compiles meshes into memory-mappable .kiln blobs of acceleration structures"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("kiln ") + kiln::kToolVersion);

  BuildArgs build;
  auto* build_cmd = app.add_subcommand("build", "Import meshes and write a .kiln blob");
  build_cmd
      ->add_option("inputs", build.inputs,
                   "Mesh files (OBJ, PLY, STL, FBX, DAE, 3DS, OFF, 3MF, glTF/GLB, DRC; "
                   "a .zst suffix is inflated first)")
      ->required();
  build_cmd->add_option("-o,--output", build.output, "The blob to write (atomically)")->required();
  build_cmd->add_flag("--compress", build.compress,
                      "zstd-compress each section (trades zero-copy mapping for size)");
  build_cmd->add_option("--compression-level", build.level, "zstd level")
      ->check(CLI::Range(1, 22))
      ->capture_default_str();
  build_cmd
      ->add_option("--threads", build.threads,
                   "Worker threads (0 = all cores); never changes the output")
      ->check(CLI::Range(0u, kMaxThreads))
      ->capture_default_str();
  build_cmd->add_flag("--stats", build.stats, "Print build time and sizes to stderr");
  build_cmd->add_option("--depfile", build.depfile,
                        "Also write a Make-syntax depfile: the output as given to -o, then every "
                        "file the import read (absolute paths)");
  build_cmd->add_option("--cache-dir", build.cache_dir,
                        "Content-addressed build cache: reuse the blob of an identical earlier "
                        "build (created if missing)");
  build_cmd->add_option("--accel", build.accels, "Acceleration structures to build (repeatable)")
      ->check(CLI::IsMember({"bvh", "sbvh", "kdtree", "points", "dag", "esvo"}))
      ->allow_extra_args(false);
  build_cmd->add_option("--bvh-builder", build.bvh_builder, "Builder for --accel bvh")
      ->check(CLI::IsMember({"binned", "sweep"}))
      ->capture_default_str();
  build_cmd
      ->add_option("--bvh-bins", build.bvh.bins, "SAH bins (binned builder, SBVH spatial splits)")
      ->check(CLI::Range(2u, 1024u))
      ->capture_default_str();
  build_cmd
      ->add_option("--bvh-max-leaf", build.bvh.max_leaf_size,
                   "Leaves larger than this are always split")
      ->check(CLI::Range(1u, 255u))
      ->capture_default_str();
  build_cmd->add_option("--bvh-traversal-cost", build.bvh.traversal_cost, "SAH node cost")
      ->check(CLI::Range(0.0f, 1000.0f))
      ->capture_default_str();
  build_cmd->add_option("--bvh-intersection-cost", build.bvh.intersection_cost, "SAH triangle cost")
      ->check(CLI::Range(0.001f, 1000.0f))
      ->capture_default_str();
  build_cmd
      ->add_option("--sbvh-alpha", build.bvh.sbvh_alpha,
                   "Try spatial splits when child overlap exceeds alpha x root area")
      ->check(CLI::Range(0.0f, 1.0f))
      ->capture_default_str();
  build_cmd
      ->add_option("--sbvh-max-duplication", build.bvh.sbvh_max_duplication,
                   "At most (1 + this) x triangles references")
      ->check(CLI::Range(0.0f, 16.0f))
      ->capture_default_str();

  build_cmd
      ->add_option("--kd-traversal-cost", build.kdtree.traversal_cost, "k-d tree SAH node cost")
      ->check(CLI::Range(0.0f, 1000.0f))
      ->capture_default_str();
  build_cmd
      ->add_option("--kd-intersection-cost", build.kdtree.intersection_cost,
                   "k-d tree SAH triangle cost")
      ->check(CLI::Range(0.001f, 1000.0f))
      ->capture_default_str();
  build_cmd
      ->add_option("--kd-empty-bonus", build.kdtree.empty_bonus,
                   "k-d tree: fraction of the cost forgiven for cutting off empty space")
      ->check(CLI::Range(0.0f, 0.99f))
      ->capture_default_str();

  build_cmd
      ->add_option("--points-split", build.points_split,
                   "Point k-d tree cut: median (balanced) or sliding-midpoint (fat cells)")
      ->check(CLI::IsMember({"median", "sliding-midpoint"}))
      ->capture_default_str();
  build_cmd
      ->add_option("--points-leaf-size", build.points.max_leaf_size,
                   "Point k-d tree: most points per leaf")
      ->check(CLI::Range(1u, kiln::kMaxPointLeafSize))
      ->capture_default_str();

  build_cmd
      ->add_option("--resolution", build.voxels.resolution,
                   "Voxel grid side (finest level) for --accel dag and esvo: a power of two, "
                   "8..16384")
      ->capture_default_str();
  build_cmd
      ->add_option("--contour-error", build.contour_error,
                   "--accel esvo: bound, in finest voxels, on the distance from any hit to the "
                   "surface; at least sqrt(3) (larger lets contoured voxels stop higher)")
      ->capture_default_str();
  build_cmd->add_flag("--no-contours", build.no_contours,
                      "--accel esvo: plain cubes, subdivided to the finest level");
  build_cmd->add_flag("--voxel-normals", build.voxels.normals,
                      "--accel dag: attach each voxel's averaged triangle normal");
  build_cmd->add_flag("--solid", build.voxels.solid,
                      "--accel dag: fill the inside too (closed meshes: kiln dump says which)");

  std::string dump_path;
  kiln::DumpOptions dump_options;
  auto* dump_cmd = app.add_subcommand("dump", "Print a blob's header, sections and manifest");
  dump_cmd->add_option("blob", dump_path, "The .kiln file")->required();
  dump_cmd->add_flag("--json", dump_options.json, "Machine-readable JSON on stdout");
  dump_cmd->add_flag("--all-meshes", dump_options.all_meshes, "List every mesh in the table");

  std::string verify_path;
  bool verify_json = false;
  auto* verify_cmd =
      app.add_subcommand("verify", "Check a blob completely, every checksum included");
  verify_cmd->add_option("blob", verify_path, "The .kiln file")->required();
  verify_cmd->add_flag("--json", verify_json, "Machine-readable JSON on stdout");

  kiln::TraceArgs trace;
  auto* trace_cmd = app.add_subcommand("trace", "Trace a RAYS file against a structure in a blob");
  trace_cmd->add_option("blob", trace.blob, "The .kiln file")->required();
  trace_cmd->add_option("--rays", trace.rays, "RAYS file: 8 float32 per ray (org, tmin, dir, tmax)")
      ->required();
  trace_cmd
      ->add_option("--out", trace.out,
                   "HITS file: float32 t, uint32 prim, float32 u, v per ray (voxel structures: "
                   "the 40-byte voxel-hit record, docs/FORMAT.md)")
      ->required();
  trace_cmd->add_option("--accel", trace.accel,
                        "Structure to use (default: the first in the blob)");
  trace_cmd->add_flag("--any-hit", trace.any_hit, "Occlusion: stop at the first hit found");
  trace_cmd->add_option("--threads", trace.threads, "Worker threads (0 = all cores)")
      ->check(CLI::Range(0u, kMaxThreads));

  kiln::RaysArgs rays;
  auto* rays_cmd =
      app.add_subcommand("rays", "Generate a reproducible RAYS file for a mesh or blob");
  rays_cmd->add_option("input", rays.input, "A mesh file or a .kiln blob with a BVH")->required();
  rays_cmd->add_option("--kind", rays.kind, "primary, diffuse or shadow")
      ->check(CLI::IsMember({"primary", "diffuse", "shadow"}))
      ->capture_default_str();
  rays_cmd->add_option("--count", rays.count, "Number of rays")
      ->check(CLI::Range(std::uint64_t{1}, std::uint64_t{1} << 28))
      ->capture_default_str();
  rays_cmd->add_option("--seed", rays.seed, "Random seed")->capture_default_str();
  rays_cmd->add_option("-o,--output", rays.out, "RAYS file to write")->required();
  rays_cmd
      ->add_option("--threads", rays.threads,
                   "Worker threads (0 = all cores); never changes the output")
      ->check(CLI::Range(0u, kMaxThreads));

  kiln::QueryArgs query;
  auto* query_cmd = app.add_subcommand(
      "query", "Closest point, inside, box, knn, radius and occupied queries on a blob");
  query_cmd->add_option("blob", query.blob, "The .kiln file")->required();
  query_cmd
      ->add_option("--op", query.op,
                   "closest, inside, box (BVH or k-d tree); knn, radius (point k-d tree); "
                   "occupied (ESVO or voxel DAG)")
      ->check(CLI::IsMember({"closest", "inside", "box", "knn", "radius", "occupied"}))
      ->required();
  query_cmd->add_option("--in", query.in, "Queries: float32 x 3 per point, x 6 per box (min, max)")
      ->required();
  query_cmd->add_option("--out", query.out, "Answers (docs/FORMAT.md)")->required();
  query_cmd->add_option("--accel", query.accel,
                        "Structure to use (default: the first BVH, else the k-d tree; knn and "
                        "radius: the point k-d tree)");
  query_cmd
      ->add_option("--max-distance", query.max_distance, "closest: ignore surfaces farther away")
      ->check(CLI::PositiveNumber);
  query_cmd->add_option("--k", query.k, "knn: neighbours per query")->check(CLI::Range(1u, 4096u));
  query_cmd->add_option("--radius", query.radius, "radius: search radius")
      ->check(CLI::NonNegativeNumber);
  query_cmd->add_option("--threads", query.threads, "Worker threads (0 = all cores)")
      ->check(CLI::Range(0u, kMaxThreads));

  kiln::RenderArgs render;
  auto* render_cmd = app.add_subcommand(
      "render", "Render a view of a blob with one of its ray structures (runtime only) to a PNG");
  render_cmd->add_option("blob", render.blob, "The .kiln file")->required();
  render_cmd->add_option("-o,--output", render.out, "The PNG to write (atomically)")->required();
  render_cmd->add_option("--accel", render.accel,
                         "bvh, sbvh, kdtree, dag or esvo (default: the first ray structure)");
  render_cmd->add_option("--mode", render.mode,
                         "shade (default), normal, depth or heatmap (node visits + primitive "
                         "tests per ray on viridis, with a legend; --compare's default)");
  render_cmd
      ->add_option("--size", render.size, "Image size WIDTHxHEIGHT, each 1..16384 (per panel)")
      ->capture_default_str();
  render_cmd->add_option("--camera", render.camera,
                         "eye_x,eye_y,eye_z,target_x,target_y,target_z,fov_degrees: seven numbers "
                         "separated by commas, no spaces; fov is vertical, 0..180 exclusive, +y "
                         "is up (default: frame the scene bounds from the front right, above)");
  render_cmd->add_option("--compare", render.compare,
                         "Structures to render side by side, e.g. bvh,sbvh,kdtree: one shared "
                         "heatmap scale, mean cost per ray in each caption and on stdout");
  render_cmd
      ->add_option("--threads", render.threads,
                   "Worker threads (0 = all cores); never changes the image")
      ->check(CLI::Range(0u, kMaxThreads));
  render_cmd->add_flag("--json", render.json, "Mean costs per structure as JSON on stdout");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  if (*build_cmd) return run_build(build);
  if (*dump_cmd) return kiln::run_dump(dump_path, dump_options, std::cout, std::cerr);
  if (*verify_cmd) return kiln::run_verify(verify_path, verify_json, std::cout, std::cerr);
  if (*trace_cmd) return kiln::run_trace(trace);
  if (*rays_cmd) return kiln::run_rays(rays);
  if (*query_cmd) return kiln::run_query(query);
  if (*render_cmd) return kiln::run_render(render);
  return 2;
}
