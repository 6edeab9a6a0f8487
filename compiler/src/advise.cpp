// `kiln advise`: every candidate ray structure built on the same (sampled) scene, the same
// reproducible rays traced through each, and a recommendation by a documented rule.
#include "kiln/compiler/advise.hpp"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <memory>
#include <optional>
#include <stdexcept>

#include "kiln/compiler/build.hpp"
#include "kiln/runtime/aligned_buffer.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/parallel.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "kiln/tools/ray_generator.hpp"

namespace kiln {

namespace {

// A candidate compiled into a blob in memory and opened through the runtime's registry, as a
// program reading the blob would see it.
struct CompiledCandidate {
  std::unique_ptr<AlignedBuffer> buffer;
  std::unique_ptr<Blob> blob;
  std::unique_ptr<StructureView> view;
  std::uint64_t bytes = 0;  // raw bytes of the structure's own sections
  double build_seconds = 0;
};

CompiledCandidate compile_candidate(const Scene& sample, const StructureRequest& request,
                                    unsigned threads) {
  BuildOptions options;
  options.structures.push_back(request);
  options.threads = threads;
  std::vector<AccelReport> reports;
  const std::vector<std::byte> bytes = compile_blob(sample, options, &reports);
  CompiledCandidate c;
  c.build_seconds = reports.empty() ? 0 : reports.front().build_seconds;
  c.buffer = std::make_unique<AlignedBuffer>(bytes.size(), 16);
  std::memcpy(c.buffer->data(), bytes.data(), bytes.size());
  c.blob = std::make_unique<Blob>(Blob::open_memory(c.buffer->bytes(), "advise: " + request.kind));
  const StructureInfo& info = c.blob->structures().front();
  for (std::uint32_t section : info.sections) c.bytes += c.blob->sections()[section].raw_size;
  c.view = open_structure(*c.blob, info.name);
  const RayQueries* rays = c.view->rays();
  if (rays == nullptr || rays->record_size() != sizeof(Hit))
    throw std::invalid_argument(request.kind +
                                " does not find triangle hits (not a triangle ray structure)");
  return c;
}

// The registry's first triangle kind, with its default options: the reference that finds the
// primary hits diffuse rays bounce from (as `kiln rays` does).
const StructureBuilder& reference_builder() {
  for (const StructureBuilder* builder : structure_builders())
    if (builder->consumes == InputKind::kTriangles && !builder->advise_skip) return *builder;
  throw std::runtime_error("no structure kind is built over triangles");
}

CompiledCandidate compile_reference(const Scene& sample, unsigned threads) {
  return compile_candidate(sample, resolve_structure_request(reference_builder().kind, {}),
                           threads);
}

std::vector<Ray> rays_with(const RayQueries& reference, const Scene& sample, bool diffuse,
                           std::size_t count, std::uint64_t seed, unsigned threads) {
  const RayScene scene{reference, sample.positions, sample.triangles, sample.bounds.min,
                       sample.bounds.max};
  return generate_rays(scene, diffuse ? RayKind::kDiffuse : RayKind::kPrimary, count, seed,
                       threads);
}

double median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n == 0 ? 0 : n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

// Half the range of the runs relative to their median: how far the median may be off.
double spread(const std::vector<double>& values) {
  const double m = median(values);
  if (values.empty() || m <= 0) return 0;
  const auto [lo, hi] = std::minmax_element(values.begin(), values.end());
  return 0.5 * (*hi - *lo) / m;
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

struct RaySet {
  std::string kind;
  std::vector<Ray> rays;
};

// Mean node visits and tests per ray (each ray counts into its own slot, summed in order: the
// same numbers on any thread count).
void count_cost(const RayQueries& view, const RaySet& set, unsigned threads,
                AdviseRayMeasure& measure) {
  std::vector<Cost> costs(set.rays.size());
  parallel_for_batched(set.rays.size(), kRaysPerTask, threads,
                       [&](std::size_t i) { view.intersect_counting(set.rays[i], costs[i]); });
  std::uint64_t nodes = 0, tests = 0;
  for (const Cost& c : costs) nodes += c.nodes, tests += c.tests;
  const double n = double(std::max<std::size_t>(set.rays.size(), 1));
  measure.nodes_per_ray = double(nodes) / n;
  measure.tests_per_ray = double(tests) / n;
}

// Median seconds of `repetitions` closest-hit traces of the set; its spread into `noise`.
double time_trace(const RayQueries& view, const RaySet& set, const AdviseOptions& options,
                  double& noise) {
  std::vector<std::byte> records(set.rays.size() * view.record_size());
  std::vector<double> seconds;
  for (unsigned r = 0; r < options.repetitions; ++r) {
    const auto start = std::chrono::steady_clock::now();
    view.trace_records(set.rays, records, false, options.threads);
    seconds.push_back(seconds_since(start));
  }
  noise = std::max(noise, spread(seconds));
  return median(seconds);
}

AdviceRow measure(const Scene& sample, const std::string& spec, std::span<const RaySet> sets,
                  const AdviseOptions& options) {
  const StructureRequest request = resolve_structure_request(spec, {});
  AdviceRow row;
  row.spec = spec;
  row.kind = request.kind;
  std::vector<double> builds;
  CompiledCandidate c;
  // Builds are the slow part: timed once unless build time is the priority.
  const unsigned builds_wanted =
      options.priority == AdvisePriority::kBuild ? std::max(1u, options.repetitions) : 1;
  for (unsigned r = 0; r < builds_wanted; ++r) {
    c = compile_candidate(sample, request, options.threads);
    builds.push_back(c.build_seconds);
  }
  row.build_ms = options.repetitions ? median(builds) * 1e3 : 0;
  row.bytes = c.bytes;
  row.bytes_per_triangle =
      double(c.bytes) / double(std::max<std::size_t>(sample.triangles.size(), 1));
  double total_seconds = 0, total_cost = 0;
  std::size_t total_rays = 0;
  for (const RaySet& set : sets) {
    AdviseRayMeasure& m = row.rays.emplace_back();
    m.kind = set.kind;
    count_cost(*c.view->rays(), set, options.threads, m);
    total_cost += (m.nodes_per_ray + m.tests_per_ray) * double(set.rays.size());
    total_rays += set.rays.size();
    if (options.repetitions == 0) continue;
    const double seconds = time_trace(*c.view->rays(), set, options, row.noise);
    m.mrays_per_s = seconds > 0 ? double(set.rays.size()) / seconds * 1e-6 : 0;
    total_seconds += seconds;
  }
  row.cost_per_ray = total_cost / double(std::max<std::size_t>(total_rays, 1));
  row.mrays_per_s = total_seconds > 0 ? double(total_rays) / total_seconds * 1e-6 : 0;
  return row;
}

std::string fixed(double value, int digits) {
  char text[64];
  std::snprintf(text, sizeof text, "%.*f", digits, value);
  return text;
}

// Index of the best row by `better` among rows where `eligible` holds (the first on ties).
template <class Eligible, class Better>
std::size_t pick(std::span<const AdviceRow> rows, Eligible eligible, Better better) {
  std::optional<std::size_t> best;
  for (std::size_t i = 0; i < rows.size(); ++i)
    if (eligible(rows[i]) && (!best || better(rows[i], rows[*best]))) best = i;
  return best.value_or(0);
}

Recommendation recommend_trace(std::span<const AdviceRow> rows, bool timed) {
  const auto cheaper = [](const AdviceRow& a, const AdviceRow& b) {
    return a.cost_per_ray < b.cost_per_ray;
  };
  if (!timed) {
    const std::size_t i = pick(
        rows, [](const AdviceRow&) { return true; }, cheaper);
    return {i, "lowest traversal cost per ray (" + fixed(rows[i].cost_per_ray, 1) +
                   " node visits + triangle tests), a deterministic stand-in for speed"};
  }
  double fastest = 0, noise = kNoiseFloor;
  for (const AdviceRow& r : rows)
    fastest = std::max(fastest, r.mrays_per_s), noise = std::max(noise, r.noise);
  noise = std::min(noise, kNoiseCeiling);
  const auto tied = [&](const AdviceRow& r) { return r.mrays_per_s >= fastest * (1 - noise); };
  const std::size_t i = pick(rows, tied, cheaper);
  std::size_t ties = 0;
  for (const AdviceRow& r : rows) ties += tied(r);
  if (ties == 1) return {i, "highest Mrays/s (" + fixed(rows[i].mrays_per_s, 2) + ")"};
  return {i, "lowest traversal cost per ray (" + fixed(rows[i].cost_per_ray, 1) + ") among the " +
                 std::to_string(ties) + " structures within " + fixed(noise * 100, 0) +
                 "% (timing noise) of the highest Mrays/s"};
}

Recommendation recommend_memory(std::span<const AdviceRow> rows, bool timed) {
  double fastest = 0, cheapest = rows.front().cost_per_ray;
  for (const AdviceRow& r : rows)
    fastest = std::max(fastest, r.mrays_per_s), cheapest = std::min(cheapest, r.cost_per_ray);
  const auto fast_enough = [&](const AdviceRow& r) {
    return timed ? r.mrays_per_s >= fastest * (1 - kWithinTrace)
                 : r.cost_per_ray <= cheapest * (1 + kWithinTrace);
  };
  const std::size_t i = pick(rows, fast_enough, [](const AdviceRow& a, const AdviceRow& b) {
    return a.bytes_per_triangle < b.bytes_per_triangle ||
           (a.bytes_per_triangle == b.bytes_per_triangle && a.cost_per_ray < b.cost_per_ray);
  });
  return {i, "fewest bytes per triangle (" + fixed(rows[i].bytes_per_triangle, 1) +
                 ") among the structures within " + fixed(kWithinTrace * 100, 0) +
                 "% of the best " + (timed ? "Mrays/s" : "traversal cost per ray")};
}

Recommendation recommend_build(std::span<const AdviceRow> rows, bool timed) {
  if (!timed)
    throw std::invalid_argument(
        "the build priority needs timing, which differs run to run (use kiln advise --for build "
        "and name the structure)");
  double quickest = rows.front().build_ms;
  for (const AdviceRow& r : rows) quickest = std::min(quickest, r.build_ms);
  const auto tied = [&](const AdviceRow& r) { return r.build_ms <= quickest * (1 + kNoiseFloor); };
  const std::size_t i = pick(rows, tied, [](const AdviceRow& a, const AdviceRow& b) {
    return a.cost_per_ray < b.cost_per_ray;
  });
  return {i, "fastest build (" + fixed(rows[i].build_ms, 1) + " ms" +
                 (rows[i].build_ms > quickest ? ", within " + fixed(kNoiseFloor * 100, 0) +
                                                    "% of the fastest, with a lower cost per ray)"
                                              : ")")};
}

}  // namespace

std::string_view priority_name(AdvisePriority priority) {
  switch (priority) {
    case AdvisePriority::kTrace:
      return "trace";
    case AdvisePriority::kMemory:
      return "memory";
    case AdvisePriority::kBuild:
      return "build";
  }
  return "?";
}

std::string_view rays_name(AdviseRays rays) {
  switch (rays) {
    case AdviseRays::kPrimary:
      return "primary";
    case AdviseRays::kDiffuse:
      return "diffuse";
    case AdviseRays::kBoth:
      return "both";
  }
  return "?";
}

AdvisePriority parse_priority(std::string_view text) {
  for (auto p : {AdvisePriority::kTrace, AdvisePriority::kMemory, AdvisePriority::kBuild})
    if (priority_name(p) == text) return p;
  throw std::invalid_argument("'" + std::string(text) + "' is not trace, memory or build");
}

AdviseRays parse_rays(std::string_view text) {
  for (auto r : {AdviseRays::kPrimary, AdviseRays::kDiffuse, AdviseRays::kBoth})
    if (rays_name(r) == text) return r;
  throw std::invalid_argument("'" + std::string(text) + "' is not primary, diffuse or both");
}

std::vector<std::string> advise_candidates() {
  std::vector<std::string> specs;
  for (const StructureBuilder* builder : structure_builders()) {
    if (builder->consumes != InputKind::kTriangles || builder->advise_skip) continue;
    specs.push_back(builder->kind);
    specs.insert(specs.end(), builder->advise_variants.begin(), builder->advise_variants.end());
  }
  return specs;
}

Scene advise_sample(const Scene& scene, std::uint64_t cap) {
  const std::size_t n = scene.triangles.size();
  if (cap == 0 || n <= cap) return scene;
  const std::size_t stride = (n + cap - 1) / cap;
  Scene sample;
  std::vector<std::uint32_t> remap(scene.positions.size(), kNoHit);
  for (std::size_t t = 0; t < n; t += stride) {
    format::Triangle tri = scene.triangles[t];
    for (std::uint32_t& v : tri.v) {
      if (remap[v] == kNoHit) {
        remap[v] = std::uint32_t(sample.positions.size());
        sample.positions.push_back(scene.positions[v]);
      }
      v = remap[v];
    }
    sample.triangles.push_back(tri);
  }
  sample.triangle_mesh.assign(sample.triangles.size(), 0);
  sample.meshes.push_back({"sample", 0, 0, sample.triangles.size(), 0, sample.positions.size()});
  sample.sources = scene.sources;
  if (sample.sources.empty()) sample.sources.push_back({"<sample>", 0, 0});  // the mesh names one
  sample.input_triangle_count = sample.triangles.size();
  sample.bounds = bounds_of(sample.positions);
  return sample;
}

std::vector<Ray> advise_rays(const Scene& sample, bool diffuse, std::size_t count,
                             std::uint64_t seed, unsigned threads) {
  const CompiledCandidate reference = compile_reference(sample, threads);
  return rays_with(*reference.view->rays(), sample, diffuse, count, seed, threads);
}

Advice advise(const Scene& scene, const AdviseOptions& options) {
  if (scene.triangles.empty()) throw std::invalid_argument("the input has no triangles");
  const std::vector<std::string> specs =
      options.candidates.empty() ? advise_candidates() : options.candidates;
  for (const std::string& spec : specs) resolve_structure_request(spec, {});  // fail early
  Advice advice;
  advice.scene_triangles = scene.triangles.size();
  const Scene sample = advise_sample(scene, options.sample_triangles);
  advice.sample_triangles = sample.triangles.size();
  advice.rays_per_kind = options.rays_per_kind;
  advice.seed = options.seed;
  advice.priority = options.priority;
  advice.timed = options.repetitions > 0;
  const std::uint64_t steps = specs.size() + 1;
  if (options.progress) options.progress("rays", 0, steps);
  std::vector<RaySet> sets;
  const CompiledCandidate reference = compile_reference(sample, options.threads);
  for (const bool diffuse : {false, true}) {
    if ((diffuse && options.rays == AdviseRays::kPrimary) ||
        (!diffuse && options.rays == AdviseRays::kDiffuse))
      continue;
    try {
      sets.push_back({diffuse ? "diffuse" : "primary",
                      rays_with(*reference.view->rays(), sample, diffuse, options.rays_per_kind,
                                options.seed, options.threads)});
    } catch (const std::runtime_error& e) {
      // Too few primary hits to bounce from: with both kinds asked, primary rays still decide.
      if (options.rays != AdviseRays::kBoth) throw;
      advice.notes.push_back(std::string("no diffuse rays: ") + e.what());
      continue;
    }
    advice.ray_kinds.push_back(sets.back().kind);
  }
  for (std::size_t i = 0; i < specs.size(); ++i) {
    if (options.progress) options.progress(specs[i], i + 1, steps);
    try {
      advice.rows.push_back(measure(sample, specs[i], sets, options));
    } catch (const std::bad_alloc&) {
      throw;
    } catch (const std::exception& e) {
      // One structure that cannot be built here (or traces no triangles) leaves the others.
      advice.notes.push_back(specs[i] + " left out: " + e.what());
    }
  }
  if (options.progress) options.progress("done", steps, steps);
  if (advice.rows.empty())
    throw std::invalid_argument("no candidate could be measured" +
                                (advice.notes.empty() ? "" : " (" + advice.notes.front() + ")"));
  advice.recommendation = recommend(advice.rows, options.priority, advice.timed);
  return advice;
}

Recommendation recommend(std::span<const AdviceRow> rows, AdvisePriority priority, bool timed) {
  if (rows.empty()) throw std::invalid_argument("no candidate structure to recommend");
  switch (priority) {
    case AdvisePriority::kTrace:
      return recommend_trace(rows, timed);
    case AdvisePriority::kMemory:
      return recommend_memory(rows, timed);
    case AdvisePriority::kBuild:
      return recommend_build(rows, timed);
  }
  throw std::invalid_argument("unknown priority");
}

}  // namespace kiln
