// `kiln build`: the structure options come from the compiler's registry (each kind's global
// flags, and `--accel KIND[:key=value,...]`), the rest is the build job's.
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "commands.hpp"
#include "kiln/compiler/advise.hpp"
#include "kiln/compiler/build.hpp"
#include "kiln/compiler/build_job.hpp"
#include "kiln/compiler/geo_import.hpp"
#include "kiln/compiler/structure_builder.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/parallel.hpp"
#include "progress.hpp"

namespace kiln::cli {

namespace {

struct BuildArgs {
  std::vector<std::string> inputs;
  std::string output, depfile, cache_dir;
  bool compress = false;
  int level = 9;
  unsigned threads = 0;
  bool stats = false;
  ImportLimits limits;
  GeoImportOptions geo;
  std::string lon_column, lat_column;         // --lon-column/--lat-column: geo.x_column/y_column
  std::vector<std::string> accels;            // as given: KIND[:key=value,...]
  std::map<std::string, std::string> values;  // global structure flag -> its value text
  std::map<std::string, CLI::Option*> flags;  // global structure flag -> its option
  EventColumns events;                        // issue 18: --lat/--lon/--time/--category
  std::vector<std::string> categories;
};

// Issue 18: the flags that read a CSV as an event table (add_event_flags, build_options).
void add_event_flags(CLI::App* command, BuildArgs& args) {
  command->add_option("--lat", args.events.lat, "Event table: the latitude column");
  command->add_option("--lon", args.events.lon, "Event table: the longitude column");
  command->add_option("--time", args.events.time,
                      "Event table: the time column (ISO 8601 with Z or an offset, or Unix s)");
  command->add_option("--category", args.categories,
                      "Event table: a categorical dimension (repeatable): COLUMN, NAME=COLUMN, "
                      "or NAME=COLUMN:E0,E1,... to cut a numeric column at edges (-inf, inf ok)");
}

// Adds every structure kind's global flags, each once (flags may be shared between kinds; the
// first kind declaring one gives its help and shown default).
void add_structure_flags(CLI::App* command, BuildArgs& args) {
  for (const StructureBuilder* builder : structure_builders())
    for (const StructureOption& option : builder->options) {
      if (option.flag.empty() || args.flags.count(option.flag) != 0) continue;
      args.flags[option.flag] =
          option.is_switch ? command->add_flag(option.flag, option.help)
                           : command->add_option(option.flag, args.values[option.flag], option.help)
                                 ->default_str(option.default_value);
    }
}

// `kiln build --help`'s list of structure kinds, one line each.
std::string kinds_footer() {
  std::string text = "Structure kinds (--accel KIND[:key=value,...]):";
  for (const StructureBuilder* builder : structure_builders()) {
    char line[512];
    std::snprintf(line, sizeof line, "\n  %-8s %s", builder->kind.c_str(), builder->help.c_str());
    text += line;
    std::string keys = "name";
    for (const StructureOption& option : builder->options)
      keys +=
          ", " + option.key + "=" + (option.default_value.empty() ? "..." : option.default_value);
    text += "\n           keys: " + keys;
  }
  text +=
      "\n  auto     The structure kiln advise recommends on this input, chosen from deterministic"
      "\n           measures (traversal cost, bytes); recorded in the manifest"
      "\n           keys: name, for=trace (or memory), rays=both (or primary, diffuse)";
  return text;
}

// Only the flags the user gave: flag -> value ("true" for a switch).
std::map<std::string, std::string> given_flags(const BuildArgs& args) {
  std::map<std::string, std::string> given;
  for (const auto& [flag, option] : args.flags)
    if (option->count() > 0) given[flag] = args.values.count(flag) ? args.values.at(flag) : "true";
  return given;
}

// Whether an output path names an input or the blob names the depfile: exit 2 with a line.
bool paths_clash(const BuildArgs& args) {
  namespace fs = std::filesystem;
  std::error_code ec;
  for (const auto& input : args.inputs)
    for (const auto& out : {args.output, args.depfile})
      if (!out.empty() && fs::exists(out, ec) && fs::equivalent(input, out, ec)) {
        std::cerr << "kiln build: output " << out << " is also an input\n";
        return true;
      }
  if (!args.depfile.empty() &&
      (args.depfile == args.output ||
       (fs::exists(args.output, ec) && fs::equivalent(args.depfile, args.output, ec)))) {
    std::cerr << "kiln build: --depfile names the output blob\n";
    return true;
  }
  return false;
}

// --stats: the blob's size and input, the time, the peak memory, one line per structure.
void print_stats(const BuildArgs& args, const BuildJobReport& job, double seconds) {
  const Blob blob = Blob::open_file(args.output);
  const InputInfo& input = blob.input();
  const bool layer = input.kind == InputKind::kPolygons2 || input.kind == InputKind::kPoint2;
  std::fprintf(
      stderr, "kiln build: %s: %llu %s, %llu %s, %llu bytes in %.3f s (%u threads)\n",
      args.output.c_str(), (unsigned long long)(layer ? input.feature_count : input.triangle_count),
      layer ? "features" : "triangles", (unsigned long long)input.vertex_count,
      input.kind == InputKind::kPoint2 ? "points" : "vertices",
      (unsigned long long)blob.header().file_size, seconds, resolve_thread_count(args.threads));
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  std::fprintf(stderr, "kiln build: peak memory %.1f MiB\n", double(usage.ru_maxrss) / 1024.0);
  for (const AccelReport& r : job.accels) {
    const StructureBuilder* builder = find_structure_builder(r.kind);
    const bool triangles = builder != nullptr && builder->consumes == InputKind::kTriangles;
    const double count = double(triangles ? input.triangle_count : input.vertex_count);
    std::fprintf(stderr, "kiln build: %s (%s): built in %.3f s (%.2f %s/s), %s\n", r.name.c_str(),
                 r.kind.c_str(), r.build_seconds, count / r.build_seconds * 1e-6,
                 triangles                          ? "Mtris"
                 : input.kind == InputKind::kPoint2 ? "Mpoints"
                                                    : "Mvertices",
                 r.summary.c_str());
  }
}

// The build options, every --accel resolved against the registry; throws
// std::invalid_argument with one line.
BuildOptions build_options(const BuildArgs& args) {
  BuildOptions options;
  options.inputs = args.inputs;
  const auto flags = given_flags(args);
  for (const auto& spec : args.accels)
    options.structures.push_back(is_auto_spec(spec) ? resolve_auto_request(spec)
                                                    : resolve_structure_request(spec, flags));
  options.compression = {args.compress, args.level};
  options.threads = args.threads;
  options.limits = args.limits;
  options.events = args.events;  // issue 18
  for (const auto& category : args.categories)
    options.events.categories.push_back(parse_event_category(category));
  options.geo = args.geo;
  options.events.skip_invalid = args.geo.skip_invalid;  // one --skip-invalid for both readers
  resolve_point_columns(options.geo, args.lon_column, args.lat_column, args.inputs);
  return options;
}

int run_build(const BuildArgs& args) {
  if (paths_clash(args)) return 2;
  // Under a file size limit (`ulimit -f`) a write past it raises SIGXFSZ, whose default action
  // kills kiln before it can remove its temporary or say why. Ignored, the write fails with
  // EFBIG: one line naming the file, the temporary removed, the previous output untouched.
  std::signal(SIGXFSZ, SIG_IGN);
  const auto start = std::chrono::steady_clock::now();
  BuildJobReport job;
  try {
    const BuildOptions options = build_options(args);
    TerminalProgress progress;
    job = run_build_job({options, args.output, args.depfile, args.cache_dir},
                        [&](std::string_view stage, std::uint64_t done, std::uint64_t total) {
                          progress.update(stage, done, total);
                        });
  } catch (const std::bad_alloc&) {
    std::cerr << "kiln build: out of memory\n";
    return 1;
  } catch (const std::exception& e) {  // ImportError, std::invalid_argument, write failures
    std::cerr << "kiln build: " << e.what() << "\n";
    return 1;
  }
  for (const auto& warning : job.warnings) std::cerr << "kiln build: warning: " << warning << "\n";
  if (job.cache_hit) std::cerr << "kiln build: cache hit " << job.cache_key << "\n";
  if (args.stats && !job.cache_key.empty() && !job.cache_hit)
    std::cerr << "kiln build: cache miss " << job.cache_key << "\n";
  if (args.stats)
    print_stats(args, job,
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  return 0;
}

// How a 2D input is read (geo_import.hpp).
void add_geo_flags(CLI::App* command, BuildArgs& args) {
  command
      ->add_option("--name-property", args.geo.name_property,
                   "GeoJSON: the feature property kept as each feature's name")
      ->capture_default_str();
  command->add_option("--lon-column", args.lon_column,
                      "CSV points: the longitude (x) column, by header name");
  command->add_option("--lat-column", args.lat_column,
                      "CSV points: the latitude (y) column, by header name");
  command->add_option("--x-column", args.geo.x_column, "CSV points: the x column (= --lon-column)");
  command->add_option("--y-column", args.geo.y_column, "CSV points: the y column (= --lat-column)");
  command->add_flag("--skip-invalid", args.geo.skip_invalid,
                    "GeoJSON/CSV: drop a broken feature or row (kept empty, counted in the "
                    "blob) instead of refusing the input");
}

}  // namespace

Command add_build_command(CLI::App& app) {
  auto args = std::make_shared<BuildArgs>();
  auto* command = app.add_subcommand("build", "Import meshes and write a .kiln blob");
  command
      ->add_option("inputs", args->inputs,
                   "Mesh files (OBJ, PLY, STL, FBX, DAE, 3DS, OFF, 3MF, glTF/GLB, DRC), or one "
                   "2D input: GeoJSON (.geojson, .json) or a CSV point table (.csv); a .zst "
                   "suffix is inflated first")
      ->required();
  command->add_option("-o,--output", args->output, "The blob to write (atomically)")->required();
  command->add_flag("--compress", args->compress,
                    "zstd-compress each section (trades zero-copy mapping for size)");
  command->add_option("--compression-level", args->level, "zstd level")
      ->check(CLI::Range(1, 22))
      ->capture_default_str();
  add_threads_option(command, args->threads,
                     "Worker threads (0 = all cores); never changes the output")
      ->capture_default_str();
  command->add_flag("--stats", args->stats, "Print build time and sizes to stderr");
  command->add_option("--depfile", args->depfile,
                      "Also write a Make-syntax depfile: the output as given to -o, then every "
                      "file the import read (absolute paths)");
  command->add_option("--cache-dir", args->cache_dir,
                      "Content-addressed build cache: reuse the blob of an identical earlier "
                      "build (created if missing)");
  command
      ->add_option("--max-inflated-size", args->limits.max_inflated_bytes,
                   "Refuse a .zst input that inflates to more than this (bytes; KiB, MiB, GiB "
                   "suffixes)")
      ->transform(CLI::AsSizeValue(false))
      ->default_str("4GiB");
  command
      ->add_option("--max-face-vertices", args->limits.max_face_vertices,
                   "Refuse an OBJ polygon with more corners than this")
      ->check(CLI::Range(3u, 1u << 30))
      ->capture_default_str();
  add_geo_flags(command, *args);
  command
      ->add_option("--accel", args->accels,
                   "A structure to build (repeatable): KIND[:key=value,...], each key an option "
                   "of the kind (its global flag sets it for every structure of the kind), "
                   "name=NAME to name it (default: the kind)")
      ->allow_extra_args(false);
  add_structure_flags(command, *args);
  add_event_flags(command, *args);
  command->footer(kinds_footer());
  return {command, [args] { return run_build(*args); }};
}

}  // namespace kiln::cli
