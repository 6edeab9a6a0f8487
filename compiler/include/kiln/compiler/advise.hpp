// `kiln advise` as a library: build every ray structure the registry has on a (sampled) scene,
// trace the same reproducible rays through each, measure, and recommend one per priority. Also
// what `kiln build --accel auto` runs to choose its structure.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "kiln/compiler/scene.hpp"
#include "kiln/compiler/structure_builder.hpp"
#include "kiln/runtime/ray.hpp"

namespace kiln {

/// What the recommendation optimises.
enum class AdvisePriority { kTrace, kMemory, kBuild };
/// Which reproducible ray sets are traced.
enum class AdviseRays { kPrimary, kDiffuse, kBoth };

std::string_view priority_name(AdvisePriority priority);  ///< "trace", "memory", "build"
std::string_view rays_name(AdviseRays rays);              ///< "primary", "diffuse", "both"
/// Parses the names above; throws std::invalid_argument with one line otherwise.
AdvisePriority parse_priority(std::string_view text);
AdviseRays parse_rays(std::string_view text);

struct AdviseOptions {
  AdvisePriority priority = AdvisePriority::kTrace;
  AdviseRays rays = AdviseRays::kBoth;
  unsigned threads = 0;  ///< 0 = all cores; never changes the deterministic columns
  /// Scenes with more triangles are measured on a deterministic sample of this many.
  std::uint64_t sample_triangles = 100000;
  std::size_t rays_per_kind = 32768;
  std::uint64_t seed = 1;
  /// Timed runs per measurement (the median is kept); 0: no timing at all, only the
  /// deterministic columns (bytes, traversal cost), as `--accel auto` uses.
  unsigned repetitions = 3;
  /// `--accel` specs to compare; empty: advise_candidates().
  std::vector<std::string> candidates;
  /// (stage, done, total), from the calling thread.
  std::function<void(std::string_view, std::uint64_t, std::uint64_t)> progress;
};

/// One ray kind through one structure.
struct AdviseRayMeasure {
  std::string kind;          ///< "primary" or "diffuse"
  double mrays_per_s = 0;    ///< median over the repetitions (0 when untimed)
  double nodes_per_ray = 0;  ///< mean node visits (intersect_counting), deterministic
  double tests_per_ray = 0;  ///< mean primitive tests, deterministic
};

/// One candidate structure, measured on the sample.
struct AdviceRow {
  std::string spec;  ///< the `--accel` spec tried
  std::string kind;
  double build_ms = 0;      ///< build time: one build, the median of the repetitions for kBuild
  std::uint64_t bytes = 0;  ///< raw bytes of the structure's own sections in the blob
  double bytes_per_triangle = 0;
  std::vector<AdviseRayMeasure> rays;  ///< one per traced ray kind
  double mrays_per_s = 0;              ///< over every traced ray: total rays / total median time
  double cost_per_ray = 0;             ///< mean node visits + primitive tests over every traced ray
  double noise = 0;  ///< half the spread of its timed trace runs over their median (worst kind)
};

/// The row a rule picked, and why, in one line.
struct Recommendation {
  std::size_t row = 0;
  std::string reason;
};

struct Advice {
  std::uint64_t scene_triangles = 0;
  std::uint64_t sample_triangles = 0;  ///< == scene_triangles when the scene was not sampled
  std::size_t rays_per_kind = 0;
  std::uint64_t seed = 0;
  std::vector<std::string> ray_kinds;
  std::vector<AdviceRow> rows;  ///< candidate order
  AdvisePriority priority = AdvisePriority::kTrace;
  bool timed = true;
  Recommendation recommendation;
  std::vector<std::string> notes;  ///< what was left out, one line each
  bool sampled() const { return sample_triangles < scene_triangles; }
};

/// The specs advise compares: each registered kind built over triangles with its default
/// options, then the variants its builder lists (StructureBuilder::advise_variants), skipping
/// kinds whose hits only approximate the surface (StructureBuilder::advise_skip). Registry
/// order, so kinds added later appear without any change here.
std::vector<std::string> advise_candidates();

/// The scene itself when it has at most `cap` triangles, else every k-th triangle (k = ceil(n /
/// cap), so density stays proportional everywhere) with the vertices they use, in one mesh.
Scene advise_sample(const Scene& scene, std::uint64_t cap);

/// The reproducible rays of one kind advise traces on a (sampled) scene: `kiln rays`'s generator
/// (camera framing the bounds; diffuse bounces from the hits found by the registry's first
/// triangle kind with its default options).
std::vector<Ray> advise_rays(const Scene& sample, bool diffuse, std::size_t count,
                             std::uint64_t seed, unsigned threads);

/// Builds, traces and measures every candidate on a sample of `scene`, and recommends one for
/// `options.priority` (recommend()). A candidate that fails to build or to trace triangle hits
/// is left out with a note. Throws std::invalid_argument for a bad candidate spec, an input
/// without triangles or no candidate left, std::runtime_error when the rays cannot be made.
Advice advise(const Scene& scene, const AdviseOptions& options);

/// The documented rules (README "Which ray structure"). `kNoiseFloor` and `kWithinTrace` below.
///  - trace, timed: the highest Mrays/s; rows within the noise of the fastest (the largest
///    AdviceRow::noise, at least kNoiseFloor, at most kNoiseCeiling) count as tied, and the tie
///    goes to the lowest traversal cost per ray. Untimed: the lowest traversal cost per ray.
///  - memory: the fewest bytes per triangle among rows within kWithinTrace of the best trace
///    measure (Mrays/s, or cost per ray when untimed); ties to the lower cost per ray.
///  - build: the fastest median build, rows within kNoiseFloor tied, ties to the lower cost per
///    ray. Needs timing: throws std::invalid_argument when untimed.
/// Remaining ties go to the earlier row (registry order). Throws std::invalid_argument on no rows.
Recommendation recommend(std::span<const AdviceRow> rows, AdvisePriority priority, bool timed);

inline constexpr double kNoiseFloor = 0.10;    ///< timings closer than 10% are a tie
inline constexpr double kNoiseCeiling = 0.50;  ///< however noisy, 2x faster is never a tie
inline constexpr double kWithinTrace = 0.25;   ///< memory trades at most 25% of trace speed

/// `--accel auto[:for=trace|memory,rays=primary|diffuse|both,name=NAME]` as a request of kind
/// "auto" (no builder: compile_blob resolves it on the scene). Throws std::invalid_argument.
StructureRequest resolve_auto_request(std::string_view spec);
bool is_auto_spec(std::string_view spec);
inline constexpr std::string_view kAutoKind = "auto";

/// What `--accel auto` chose: the request it became, and the untimed advice behind it.
struct AutoChoice {
  std::size_t structure = 0;  ///< its index in the blob's structures
  std::string spec;           ///< the chosen candidate spec
  Advice advice;
};

/// Replaces every "auto" request by the candidate advise recommends on `scene` (untimed: the
/// choice depends on deterministic measures only, so the blob does not depend on the run or the
/// thread count). The structure keeps the auto request's name, else the chosen kind's.
std::vector<AutoChoice> resolve_auto_requests(const Scene& scene,
                                              std::vector<StructureRequest>& requests,
                                              unsigned threads);

}  // namespace kiln
