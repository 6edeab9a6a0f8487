// `kiln advise`: every ray structure of the registry built on the input (a sample of it when
// large), the same reproducible rays traced through each, one table and a recommendation.
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "commands.hpp"
#include "kiln/compiler/advise.hpp"
#include "kiln/compiler/build.hpp"
#include "progress.hpp"

namespace kiln::cli {

namespace {

struct AdviseArgs {
  std::vector<std::string> inputs;
  std::string priority = "trace";
  std::string rays = "both";
  bool json = false;
  unsigned threads = 0;
  std::uint64_t sample = AdviseOptions{}.sample_triangles;
  std::size_t count = AdviseOptions{}.rays_per_kind;
  std::uint64_t seed = AdviseOptions{}.seed;
  unsigned repeat = AdviseOptions{}.repetitions;
  std::vector<std::string> candidates;
};

std::string printf_string(const char* format, auto... args) {
  char text[512];
  std::snprintf(text, sizeof text, format, args...);
  return text;
}

void print_table(const Advice& advice, std::ostream& out) {
  const std::string sample =
      advice.sampled()
          ? printf_string(
                "a sample of %llu of its %llu triangles (1 in %llu)",
                (unsigned long long)advice.sample_triangles,
                (unsigned long long)advice.scene_triangles,
                (unsigned long long)((advice.scene_triangles + advice.sample_triangles - 1) /
                                     advice.sample_triangles))
          : printf_string("all %llu triangles", (unsigned long long)advice.scene_triangles);
  out << "kiln advise: measured on " << sample << ", " << advice.rays_per_kind
      << " rays per kind (seed " << advice.seed << "), medians of the timed runs\n\n";
  std::string header = printf_string("  %-24s %10s %10s", "structure", "build ms", "bytes/tri");
  for (const std::string& kind : advice.ray_kinds)
    header += printf_string(" %10s", (kind + " Mr/s").c_str());
  out << header << printf_string(" %9s %7s\n", "cost/ray", "noise");
  for (std::size_t i = 0; i < advice.rows.size(); ++i) {
    const AdviceRow& r = advice.rows[i];
    std::string line =
        printf_string("%c %-24s %10.1f %10.1f", i == advice.recommendation.row ? '*' : ' ',
                      r.spec.c_str(), r.build_ms, r.bytes_per_triangle);
    for (const AdviseRayMeasure& m : r.rays) line += printf_string(" %10.2f", m.mrays_per_s);
    out << line << printf_string(" %9.1f %6.0f%%\n", r.cost_per_ray, r.noise * 100);
  }
  for (const std::string& note : advice.notes) out << "note: " << note << "\n";
  out << "\ncost/ray: mean node visits + triangle tests per ray (deterministic); noise: spread "
         "of the timed runs\n";
  out << "recommended for " << priority_name(advice.priority) << ": "
      << advice.rows[advice.recommendation.row].spec << " (" << advice.recommendation.reason
      << ")\n";
}

nlohmann::ordered_json advice_json(const Advice& advice) {
  using Json = nlohmann::ordered_json;
  Json rows = Json::array();
  for (const AdviceRow& r : advice.rows) {
    Json rays = Json::object();
    for (const AdviseRayMeasure& m : r.rays)
      rays[m.kind] = {{"mrays_per_s", m.mrays_per_s},
                      {"nodes_per_ray", m.nodes_per_ray},
                      {"tests_per_ray", m.tests_per_ray}};
    rows.push_back({{"spec", r.spec},
                    {"kind", r.kind},
                    {"build_ms", r.build_ms},
                    {"bytes", r.bytes},
                    {"bytes_per_triangle", r.bytes_per_triangle},
                    {"mrays_per_s", r.mrays_per_s},
                    {"cost_per_ray", r.cost_per_ray},
                    {"noise", r.noise},
                    {"rays", std::move(rays)}});
  }
  const AdviceRow& chosen = advice.rows[advice.recommendation.row];
  return {{"scene_triangles", advice.scene_triangles},
          {"sample_triangles", advice.sample_triangles},
          {"sampled", advice.sampled()},
          {"rays_per_kind", advice.rays_per_kind},
          {"seed", advice.seed},
          {"ray_kinds", advice.ray_kinds},
          {"notes", advice.notes},
          {"rows", std::move(rows)},
          {"recommendation",
           {{"priority", std::string(priority_name(advice.priority))},
            {"spec", chosen.spec},
            {"kind", chosen.kind},
            {"reason", advice.recommendation.reason}}}};
}

int run_advise(const AdviseArgs& args) {
  try {
    AdviseOptions options;
    options.priority = parse_priority(args.priority);
    options.rays = parse_rays(args.rays);
    options.threads = args.threads;
    options.sample_triangles = args.sample;
    options.rays_per_kind = args.count;
    options.seed = args.seed;
    options.repetitions = args.repeat;
    options.candidates = args.candidates;
    TerminalProgress progress;
    options.progress = [&](std::string_view stage, std::uint64_t done, std::uint64_t total) {
      progress.update(stage, done, total);
    };
    const Scene scene = import_scene(args.inputs, args.threads);
    const Advice advice = advise(scene, options);
    if (args.json)
      std::cout << advice_json(advice).dump(-1, ' ', false,
                                            nlohmann::json::error_handler_t::replace)
                << "\n";
    else
      print_table(advice, std::cout);
    return 0;
  } catch (const std::bad_alloc&) {
    std::cerr << "kiln advise: out of memory\n";
  } catch (const std::exception& e) {
    std::cerr << "kiln advise: " << e.what() << "\n";
  }
  return 1;
}

}  // namespace

Command add_advise_command(CLI::App& app) {
  auto args = std::make_shared<AdviseArgs>();
  auto* command = app.add_subcommand(
      "advise", "Build every ray structure on a mesh, trace the same rays, and recommend one");
  command->add_option("inputs", args->inputs, "Mesh files (as kiln build takes them)")->required();
  command->add_option("--for", args->priority, "What to optimise: trace, memory or build")
      ->check(CLI::IsMember({"trace", "memory", "build"}))
      ->capture_default_str();
  command->add_option("--rays", args->rays, "Rays to trace: primary, diffuse or both")
      ->check(CLI::IsMember({"primary", "diffuse", "both"}))
      ->capture_default_str();
  command->add_flag("--json", args->json, "Print the table and recommendation as one JSON object");
  add_threads_option(command, args->threads,
                     "Worker threads (0 = all cores); never changes the deterministic columns");
  command
      ->add_option("--sample", args->sample,
                   "Measure on every k-th triangle when the input has more than this many")
      ->check(CLI::Range(std::uint64_t{1}, std::uint64_t{1} << 32))
      ->capture_default_str();
  command->add_option("--count", args->count, "Rays per kind")
      ->check(CLI::Range(std::size_t{1}, std::size_t{1} << 24))
      ->capture_default_str();
  command->add_option("--seed", args->seed, "Seed of the ray sets")->capture_default_str();
  command->add_option("--repeat", args->repeat, "Timed runs per measurement (the median is kept)")
      ->check(CLI::Range(1u, 100u))
      ->capture_default_str();
  command->add_option("--candidate", args->candidates,
                      "Compare these --accel specs instead (repeatable), e.g. bvh:width=4");
  command->footer(
      "Rules: trace = highest Mrays/s, rows within the timing noise (at least 10%) tied and won "
      "by the lowest cost per ray; memory = fewest bytes/triangle within 25% of the best "
      "Mrays/s; build = fastest build. kiln build --accel auto chooses the same way from the "
      "deterministic columns only.");
  return {command, [args] { return run_advise(*args); }};
}

}  // namespace kiln::cli
