// `kiln advise`, its rules, `kiln build --accel auto` and the generated scenes it is shown on.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>
#include <set>

#include "kiln/bench/generated_scenes.hpp"
#include "kiln/compiler/advise.hpp"
#include "kiln/compiler/build.hpp"
#include "kiln/compiler/build_cache.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

using test::quoted;

Scene scene_of(const bench::GeneratedMesh& mesh) {
  Scene scene;
  scene.positions = mesh.positions;
  scene.triangles = mesh.triangles;
  scene.triangle_mesh.assign(mesh.triangles.size(), 0);
  scene.meshes.push_back({"generated", 0, 0, mesh.triangles.size(), 0, mesh.positions.size()});
  scene.sources.push_back({"generated", 0, 0});
  scene.input_triangle_count = mesh.triangles.size();
  scene.bounds = bounds_of(scene.positions);
  return scene;
}

// The mesh as an OBJ file, for the command line.
void write_obj(const std::string& path, const bench::GeneratedMesh& mesh) {
  std::string text;
  char line[128];
  for (const auto& p : mesh.positions) {
    std::snprintf(line, sizeof line, "v %.9g %.9g %.9g\n", p.x, p.y, p.z);
    text += line;
  }
  for (const auto& t : mesh.triangles) {
    std::snprintf(line, sizeof line, "f %u %u %u\n", t.v[0] + 1, t.v[1] + 1, t.v[2] + 1);
    text += line;
  }
  test::write_text(path, text);
}

AdviseOptions small_options() {
  AdviseOptions options;
  options.rays_per_kind = 1500;
  options.repetitions = 1;
  options.threads = 2;
  return options;
}

TEST(Advise, CandidatesAreTheRegistrysTriangleRayKinds) {
  std::vector<std::string> expected;
  for (const StructureBuilder* builder : structure_builders()) {
    if (builder->consumes != InputKind::kTriangles || builder->advise_skip) continue;
    expected.push_back(builder->kind);
    for (const std::string& variant : builder->advise_variants) expected.push_back(variant);
  }
  ASSERT_FALSE(expected.empty());
  EXPECT_EQ(advise_candidates(), expected);
  // Each candidate answers rays with triangle hits; skipped kinds are the voxel ones.
  const Scene scene = scene_of(bench::teapot_in_stadium(600, 1));
  for (const StructureBuilder* builder : structure_builders()) {
    if (builder->consumes != InputKind::kTriangles) continue;
    // Voxel kinds at a coarse grid, to stay quick.
    const bool voxels = std::any_of(builder->options.begin(), builder->options.end(),
                                    [](const StructureOption& o) { return o.key == "resolution"; });
    const AlignedBuffer bytes = test::aligned_copy(
        test::blob_with(scene, builder->kind + (voxels ? ":resolution=16" : ""), 1));
    const Blob blob = Blob::open_memory(bytes.bytes());
    const auto view = open_structure(blob, builder->kind);
    ASSERT_NE(view->rays(), nullptr) << builder->kind;
    EXPECT_EQ(view->rays()->record_size() == sizeof(Hit), !builder->advise_skip) << builder->kind;
  }
}

// Every row's bytes are its sections' sizes in a blob built alone, and its cost per ray is
// what intersect_counting gives over the same rays.
TEST(Advise, RowsMatchTheBlobAndADirectCount) {
  const Scene scene = scene_of(bench::teapot_in_stadium(3000, 2));
  const AdviseOptions options = small_options();
  const Advice advice = advise(scene, options);
  const std::vector<std::string> candidates = advise_candidates();
  ASSERT_EQ(advice.rows.size(), candidates.size());
  ASSERT_EQ(advice.ray_kinds, (std::vector<std::string>{"primary", "diffuse"}));
  EXPECT_FALSE(advice.sampled());
  const std::vector<Ray> primary = advise_rays(scene, false, options.rays_per_kind, 1, 1);
  const std::vector<Ray> diffuse = advise_rays(scene, true, options.rays_per_kind, 1, 1);
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    const AdviceRow& row = advice.rows[i];
    EXPECT_EQ(row.spec, candidates[i]);
    const AlignedBuffer bytes = test::aligned_copy(test::blob_with(scene, row.spec, 1));
    const Blob blob = Blob::open_memory(bytes.bytes());
    std::uint64_t section_bytes = 0;
    for (std::uint32_t s : blob.structures().front().sections)
      section_bytes += blob.sections()[s].raw_size;
    EXPECT_EQ(row.bytes, section_bytes) << row.spec;
    EXPECT_DOUBLE_EQ(row.bytes_per_triangle,
                     double(section_bytes) / double(scene.triangles.size()));
    const auto view = open_structure(blob, blob.structures().front().name);
    std::uint64_t work = 0;
    for (const auto* set : {&primary, &diffuse})
      for (const Ray& ray : *set) {
        Cost cost;
        view->rays()->intersect_counting(ray, cost);
        work += cost.nodes + cost.tests;
      }
    EXPECT_NEAR(row.cost_per_ray, double(work) / double(primary.size() + diffuse.size()), 1e-9)
        << row.spec;
    ASSERT_EQ(row.rays.size(), 2u);
    for (const AdviseRayMeasure& m : row.rays) EXPECT_GT(m.mrays_per_s, 0) << row.spec;
    EXPECT_GT(row.build_ms, 0) << row.spec;
  }
  EXPECT_LT(advice.recommendation.row, advice.rows.size());
  EXPECT_FALSE(advice.recommendation.reason.empty());
}

TEST(Advise, LargeScenesAreMeasuredOnAnEvenSample) {
  const Scene scene = scene_of(bench::uniform_triangles(5000, 3));
  const Scene sample = advise_sample(scene, 1000);
  ASSERT_EQ(sample.triangles.size(), 1000u);
  for (std::size_t t = 0; t < sample.triangles.size(); ++t)
    for (int c = 0; c < 3; ++c) {
      const format::Float3 a = sample.positions[sample.triangles[t].v[c]];
      const format::Float3 b = scene.positions[scene.triangles[5 * t].v[c]];
      EXPECT_TRUE(a.x == b.x && a.y == b.y && a.z == b.z) << t;
    }
  EXPECT_EQ(sample.positions.size(), 3000u);  // only the vertices kept triangles use
  AdviseOptions options = small_options();
  options.sample_triangles = 1000;
  options.rays = AdviseRays::kPrimary;
  const Advice advice = advise(scene, options);
  EXPECT_TRUE(advice.sampled());
  EXPECT_EQ(advice.scene_triangles, 5000u);
  EXPECT_EQ(advice.sample_triangles, 1000u);
  EXPECT_EQ(advice.ray_kinds, std::vector<std::string>{"primary"});
}

AdviceRow row(std::string spec, double mrays, double cost, double bytes, double build_ms,
              double noise = 0) {
  AdviceRow r;
  r.spec = std::move(spec);
  r.mrays_per_s = mrays;
  r.cost_per_ray = cost;
  r.bytes_per_triangle = bytes;
  r.build_ms = build_ms;
  r.noise = noise;
  return r;
}

TEST(AdviseRule, TraceTakesTheFastestUnlessWithinTheNoise) {
  // b is within 10% of a and cheaper per ray; c is far slower though cheapest.
  std::vector<AdviceRow> rows = {row("a", 10, 20, 50, 100), row("b", 9.5, 15, 80, 300),
                                 row("c", 4, 5, 60, 50)};
  EXPECT_EQ(recommend(rows, AdvisePriority::kTrace, true).row, 1u);
  rows[1].mrays_per_s = 8.5;  // outside 10%: the fastest wins
  EXPECT_EQ(recommend(rows, AdvisePriority::kTrace, true).row, 0u);
  rows[0].noise = 0.2;  // noisier runs widen the tie
  EXPECT_EQ(recommend(rows, AdvisePriority::kTrace, true).row, 1u);
  rows[0].noise = 5;  // capped at 50%: c, at 40% of the fastest, never ties
  EXPECT_EQ(recommend(rows, AdvisePriority::kTrace, true).row, 1u);
  rows[2].mrays_per_s = 6;
  EXPECT_EQ(recommend(rows, AdvisePriority::kTrace, true).row, 2u);
  // Untimed (--accel auto): the lowest traversal cost.
  EXPECT_EQ(recommend(rows, AdvisePriority::kTrace, false).row, 2u);
}

TEST(AdviseRule, MemoryTakesTheSmallestAmongTheFastEnough) {
  const std::vector<AdviceRow> rows = {row("a", 10, 20, 80, 100), row("b", 8, 21, 40, 100),
                                       row("c", 5, 26, 10, 100)};
  EXPECT_EQ(recommend(rows, AdvisePriority::kMemory, true).row, 1u);   // c is 50% slower
  EXPECT_EQ(recommend(rows, AdvisePriority::kMemory, false).row, 1u);  // c costs 30% more
  const std::vector<AdviceRow> tie = {row("a", 10, 20, 40, 100), row("b", 10, 18, 40, 100)};
  EXPECT_EQ(recommend(tie, AdvisePriority::kMemory, true).row, 1u);  // same bytes: cheaper
}

TEST(AdviseRule, BuildTakesTheQuickestAndNeedsTiming) {
  const std::vector<AdviceRow> rows = {row("a", 10, 20, 80, 100), row("b", 8, 15, 40, 105),
                                       row("c", 5, 5, 10, 200)};
  EXPECT_EQ(recommend(rows, AdvisePriority::kBuild, true).row, 1u);  // within 10%, cheaper
  EXPECT_THROW(recommend(rows, AdvisePriority::kBuild, false), std::invalid_argument);
  EXPECT_THROW(recommend({}, AdvisePriority::kTrace, true), std::invalid_argument);
}

TEST(AdviseCli, PrintsEveryCandidateAndParsesAsJson) {
  test::TempDir dir;
  const std::string mesh = dir.file("stadium.obj");
  write_obj(mesh, bench::teapot_in_stadium(2000, 4));
  const std::string common = "advise " + quoted(mesh) + " --count 1000 --repeat 1 --threads 2";
  const auto text = test::run_kiln(common);
  ASSERT_EQ(text.exit_code, 0) << text.err;
  for (const std::string& spec : advise_candidates())
    EXPECT_NE(text.out.find(" " + spec + " "), std::string::npos) << spec << "\n" << text.out;
  EXPECT_NE(text.out.find("recommended for trace: "), std::string::npos) << text.out;

  const auto json_run = test::run_kiln(common + " --json --for memory --rays diffuse");
  ASSERT_EQ(json_run.exit_code, 0) << json_run.err;
  const auto json = nlohmann::json::parse(json_run.out);
  ASSERT_EQ(json["rows"].size(), advise_candidates().size());
  std::set<std::string> specs;
  for (const auto& r : json["rows"]) {
    specs.insert(r["spec"].get<std::string>());
    EXPECT_TRUE(r["rays"].contains("diffuse"));
    EXPECT_FALSE(r["rays"].contains("primary"));
    EXPECT_GT(r["bytes_per_triangle"].get<double>(), 0);
  }
  EXPECT_EQ(json["recommendation"]["priority"], "memory");
  EXPECT_EQ(specs.count(json["recommendation"]["spec"].get<std::string>()), 1u);
  EXPECT_FALSE(json["recommendation"]["reason"].get<std::string>().empty());
  EXPECT_EQ(json["sampled"], false);
}

TEST(AdviseCli, BadInputAndOptionsFailWithOneLine) {
  test::TempDir dir;
  const auto help = test::run_kiln("advise --help");
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_NE(help.out.find("Usage"), std::string::npos);
  const auto missing = test::run_kiln("advise " + quoted(dir.file("none.obj")));
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_EQ(std::count(missing.err.begin(), missing.err.end(), '\n'), 1) << missing.err;
  const std::string mesh = dir.file("u.obj");
  write_obj(mesh, bench::uniform_triangles(200, 5));
  EXPECT_NE(test::run_kiln("advise " + quoted(mesh) + " --for speed").exit_code, 0);
  const auto bad = test::run_kiln("advise " + quoted(mesh) + " --candidate nosuch");
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find("unknown structure kind"), std::string::npos) << bad.err;
  // A kind without triangle hits is left out, saying so; alone, it is an error.
  const auto mixed = test::run_kiln(
      "advise " + quoted(mesh) + " --candidate points --candidate bvh:width=4 --count 200 --json");
  ASSERT_EQ(mixed.exit_code, 0) << mixed.err;
  const auto json = nlohmann::json::parse(mixed.out);
  ASSERT_EQ(json["rows"].size(), 1u);
  EXPECT_EQ(json["rows"][0]["spec"], "bvh:width=4");
  ASSERT_EQ(json["notes"].size(), 1u);
  EXPECT_NE(json["notes"][0].get<std::string>().find("points left out"), std::string::npos);
  const auto alone = test::run_kiln("advise " + quoted(mesh) + " --candidate points");
  EXPECT_EQ(alone.exit_code, 1);
  EXPECT_EQ(std::count(alone.err.begin(), alone.err.end(), '\n'), 1) << alone.err;
}

TEST(AdviseAuto, RecordsItsChoiceAndIsTheSameOnAnyThreadCount) {
  test::TempDir dir;
  const std::string mesh = dir.file("stadium.obj");
  write_obj(mesh, bench::teapot_in_stadium(2500, 6));
  for (const unsigned threads : {1u, 2u})
    ASSERT_EQ(test::run_kiln("build " + quoted(mesh) + " --accel auto --threads " +
                             std::to_string(threads) + " -o " +
                             quoted(dir.file(std::to_string(threads) + ".kiln")))
                  .exit_code,
              0);
  EXPECT_EQ(test::read_file(dir.file("1.kiln")), test::read_file(dir.file("2.kiln")));
  const auto dump = test::run_kiln("dump --json " + quoted(dir.file("1.kiln")));
  ASSERT_EQ(dump.exit_code, 0) << dump.err;
  const auto manifest = nlohmann::json::parse(dump.out)["manifest"];
  ASSERT_EQ(manifest["advice"].size(), 1u);
  const auto& advice = manifest["advice"][0];
  ASSERT_EQ(manifest["structures"].size(), 1u);
  EXPECT_EQ(advice["structure"], manifest["structures"][0]["name"]);
  EXPECT_EQ(advice["spec"], manifest["structures"][0]["kind"]);  // defaults: the spec is the kind
  EXPECT_EQ(advice["priority"], "trace");
  ASSERT_EQ(advice["rows"].size(), advise_candidates().size());
  // The choice is the row with the lowest recorded cost (untimed trace rule).
  double best = 1e300;
  std::string cheapest;
  for (const auto& r : advice["rows"]) {
    const double cost = r["nodes_per_ray"].get<double>() + r["tests_per_ray"].get<double>();
    if (cost < best) best = cost, cheapest = r["spec"];
  }
  EXPECT_EQ(advice["spec"], cheapest);
  const auto human = test::run_kiln("dump " + quoted(dir.file("1.kiln")));
  EXPECT_NE(human.out.find("--accel auto (for trace"), std::string::npos) << human.out;
  EXPECT_EQ(test::run_kiln("verify " + quoted(dir.file("1.kiln"))).exit_code, 0);
}

TEST(AdviseAuto, OptionsNameAndRefusals) {
  const Scene scene = scene_of(bench::uniform_triangles(1500, 7));
  BuildOptions options;
  options.structures = {resolve_auto_request("auto:for=memory,rays=primary,name=chosen")};
  options.threads = 2;
  const AlignedBuffer bytes = test::aligned_copy(compile_blob(scene, options));
  const Blob blob = Blob::open_memory(bytes.bytes());
  ASSERT_EQ(blob.structures().size(), 1u);
  EXPECT_EQ(blob.structures().front().name, "chosen");
  EXPECT_NE(open_structure(blob, "chosen")->rays(), nullptr);
  EXPECT_THROW(resolve_auto_request("auto:for=build"), std::invalid_argument);
  EXPECT_THROW(resolve_auto_request("auto:speed=1"), std::invalid_argument);
  EXPECT_TRUE(is_auto_spec("auto:for=trace"));
  EXPECT_FALSE(is_auto_spec("bvh"));
  // The cache key tells the priorities apart.
  BuildOptions memory = options, trace = options;
  trace.structures = {resolve_auto_request("auto:for=trace,rays=primary,name=chosen")};
  EXPECT_NE(to_hex(direct_key(memory, {}, "f")), to_hex(direct_key(trace, {}, "f")));
}

TEST(GeneratedScenes, AreDeterministicAndShaped) {
  const auto a = bench::uniform_triangles(3000, 9), b = bench::uniform_triangles(3000, 9),
             c = bench::uniform_triangles(3000, 10);
  ASSERT_EQ(a.triangles.size(), 3000u);
  EXPECT_EQ(0, std::memcmp(a.positions.data(), b.positions.data(), a.positions.size() * 12));
  EXPECT_NE(0, std::memcmp(a.positions.data(), c.positions.data(), a.positions.size() * 12));
  const format::Box3f box = bounds_of(a.positions);
  EXPECT_GT(box.min.x, -0.1f);
  EXPECT_LT(box.max.x, 1.1f);

  const auto s = bench::teapot_in_stadium(20000, 1);
  EXPECT_NEAR(double(s.triangles.size()), 20000, 1000);
  std::size_t inside = 0;
  for (const auto& t : s.triangles) {
    const format::Float3 p = s.positions[t.v[0]];
    inside += std::fabs(p.x) <= 1.001f && std::fabs(p.y) <= 1.001f && std::fabs(p.z) <= 1.001f;
  }
  EXPECT_GT(double(inside), 0.95 * double(s.triangles.size()));  // the teapot
  const format::Box3f stadium = bounds_of(s.positions);
  EXPECT_GT(stadium.max.x - stadium.min.x, 700.0f);  // the stadium
}

}  // namespace
}  // namespace kiln
