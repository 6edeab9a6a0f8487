// `kiln trace`: a RAYS file against one ray structure of a blob, into a HITS file of the
// structure's own record (docs/FORMAT.md).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "commands.hpp"
#include "kiln/runtime/atomic_file.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/mapped_file.hpp"
#include "kiln/tools/structure_choice.hpp"

namespace kiln::cli {

namespace {

struct TraceArgs {
  std::string blob, rays, out, accel;
  bool any_hit = false;
  unsigned threads = 0;
};

// Every HITS record starts with the float32 t, +inf on a miss.
std::size_t count_hits(std::span<const std::byte> records, std::size_t record_size) {
  std::size_t hits = 0;
  for (std::size_t offset = 0; offset < records.size(); offset += record_size) {
    float t;
    std::memcpy(&t, records.data() + offset, sizeof t);
    hits += !std::isinf(t);
  }
  return hits;
}

int run_trace(const TraceArgs& args) {
  try {
    const Blob blob = Blob::open_file(args.blob);
    const ChosenStructure chosen =
        choose_structure(blob, args.accel, &StructureView::rays, "trace rays");
    const RayQueries& queries = *chosen.view->rays();
    const MappedFile rays_file(args.rays);
    const auto bytes = rays_file.bytes();
    if (bytes.size() % sizeof(Ray) != 0) {
      std::cerr << "kiln trace: " << args.rays << ": size " << bytes.size()
                << " is not a multiple of 32 bytes (8 float32 per ray)\n";
      return 1;
    }
    // The mapping is page-aligned, so the rays can be read in place.
    const std::span<const Ray> rays(reinterpret_cast<const Ray*>(bytes.data()),
                                    bytes.size() / sizeof(Ray));
    std::vector<std::byte> records(rays.size() * queries.record_size());
    const auto start = std::chrono::steady_clock::now();
    queries.trace_records(rays, records, args.any_hit, args.threads);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    write_file_atomically(args.out, records);
    std::fprintf(stderr, "kiln trace: %zu rays on %s, %zu hits, %.3f Mrays/s\n", rays.size(),
                 chosen.name.c_str(), count_hits(records, queries.record_size()),
                 seconds > 0 ? double(rays.size()) / seconds * 1e-6 : 0.0);
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "kiln trace: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace

Command add_trace_command(CLI::App& app) {
  auto args = std::make_shared<TraceArgs>();
  auto* command = app.add_subcommand("trace", "Trace a RAYS file against a structure in a blob");
  command->add_option("blob", args->blob, "The .kiln file")->required();
  command->add_option("--rays", args->rays, "RAYS file: 8 float32 per ray (org, tmin, dir, tmax)")
      ->required();
  command
      ->add_option("--out", args->out,
                   "HITS file: float32 t, uint32 prim, float32 u, v per ray (voxel structures: "
                   "the 40-byte voxel-hit record, docs/FORMAT.md)")
      ->required();
  command->add_option("--accel", args->accel,
                      "Structure to use, by name (default: the first that traces rays)");
  command->add_flag("--any-hit", args->any_hit, "Occlusion: stop at the first hit found");
  add_threads_option(command, args->threads);
  return {command, [args] { return run_trace(*args); }};
}

}  // namespace kiln::cli
