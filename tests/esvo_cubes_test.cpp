// ESVO built cube by cube (each cube of the load level voxelized alone, then the levels above
// take the fragments in) against the whole grid voxelized at once, the build as it was before
// (cube_side = resolution): byte-identical words, pages, blocks, normals, colours and statistics
// on corpus meshes at 128^3-1024^3 (cubes are at least 64^3, so 64^3 has only the whole grid), with
// and without contours, on 1 and 2 threads. And a build under a small --memory-budget peaks far
// below the whole-grid build (child processes, wait4).
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <initializer_list>
#include <string>
#include <vector>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/esvo_builder.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

using format::Float3;
using namespace kiln::test;

FlatEsvo build(const Scene& scene, std::uint32_t resolution, std::uint32_t cube_side, bool contours,
               unsigned threads) {
  EsvoBuildOptions options;
  options.resolution = resolution;
  options.cube_side = cube_side;
  options.contours = contours;
  options.threads = threads;
  return build_esvo(scene, options);
}

template <class T>
bool same_bytes(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

void expect_identical(const FlatEsvo& whole, const FlatEsvo& cubes, const std::string& what) {
  EXPECT_TRUE(same_bytes(whole.words, cubes.words)) << what << ": words";
  EXPECT_TRUE(same_bytes(whole.pages, cubes.pages)) << what << ": pages";
  EXPECT_TRUE(same_bytes(whole.blocks, cubes.blocks)) << what << ": blocks";
  EXPECT_TRUE(same_bytes(whole.normals, cubes.normals)) << what << ": normals";
  EXPECT_TRUE(same_bytes(whole.colors, cubes.colors)) << what << ": colours";
  EXPECT_TRUE(same_bytes(whole.level_stats, cubes.level_stats)) << what << ": level statistics";
  EXPECT_EQ(whole.far_pointer_count, cubes.far_pointer_count) << what;
  EXPECT_EQ(whole.max_depth, cubes.max_depth) << what;
}

struct Split {
  std::uint32_t side;
  unsigned threads;
};

// The whole grid against cubes of each `splits` side (at least 64, below the resolution).
void check_mesh(const Scene& scene, std::uint32_t resolution, bool contours,
                std::initializer_list<Split> splits, const std::string& name) {
  const FlatEsvo whole = build(scene, resolution, resolution, contours, 2);
  ASSERT_GT(whole.leaf_count, 0u);
  for (const Split& split : splits) {
    const std::string what = name + " " + std::to_string(resolution) + "^3, cubes of " +
                             std::to_string(split.side) + "^3, " + std::to_string(split.threads) +
                             " thread(s)" + (contours ? "" : ", no contours");
    expect_identical(whole, build(scene, resolution, split.side, contours, split.threads), what);
  }
}

TEST(EsvoCubes, CubeByCubeIsByteIdenticalToTheWholeGrid) {
  KILN_REQUIRE_CORPUS();
  const Scene bunny = import_scene({mesh_path("stanford/stanford-bunny.obj.zst")}, 2);
  check_mesh(bunny, 128, true, {{64, 1}, {64, 2}}, "bunny");
  // Cubes above, at and below the block level (level 4).
  check_mesh(bunny, 256, true, {{64, 1}, {64, 2}, {128, 2}}, "bunny");
  if (test::kSanitized) return;  // the paths above cover the code; the rest is for scale (CI time)
  check_mesh(bunny, 512, true, {{64, 2}, {256, 2}}, "bunny");
  check_mesh(bunny, 256, false, {{64, 2}}, "bunny");
  const Scene dragon = import_scene({mesh_path("stanford/dragon_100k.obj.zst")}, 2);
  check_mesh(dragon, 256, true, {{128, 2}}, "dragon");
}

TEST(EsvoCubes, CubeByCubeKeepsColours) {
  KILN_REQUIRE_CORPUS();
  Scene spot = import_scene({mesh_path("classic/spot.obj")}, 2);
  for (const Float3& p : spot.positions) {
    const auto channel = [](float v) {
      return std::uint32_t(std::lround(127.5f + 127.5f * std::sin(9 * v)));
    };
    spot.colors.push_back(channel(p.x) | channel(p.y) << 8 | channel(p.z) << 16 | 0xFFu << 24);
  }
  check_mesh(spot, 256, true, {{64, 2}}, "spot");
}

// The largest cube side and the whole grid, once, at 1024^3 (where the top levels hold blocks).
TEST(EsvoCubes, CubeByCubeAt1024) {
  KILN_REQUIRE_CORPUS();
  if (test::kSanitized)
    GTEST_SKIP() << "the same paths run at 512^3 above; skipped for time under ASan";
  const Scene bunny = import_scene({mesh_path("stanford/stanford-bunny.obj.zst")}, 2);
  const FlatEsvo whole = build(bunny, 1024, 1024, true, 2);
  expect_identical(whole, build(bunny, 1024, 128, true, 2), "bunny 1024^3, cubes of 128^3");
}

// Peak resident bytes of the kiln CLI run with `arguments`, or -1 when it fails.
long long cli_peak_bytes(const std::vector<std::string>& arguments) {
  const pid_t child = ::fork();
  if (child == 0) {
    std::vector<char*> argv{const_cast<char*>(KILN_CLI)};
    for (const std::string& a : arguments) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    const int null = ::open("/dev/null", O_WRONLY);
    ::dup2(null, 1), ::dup2(null, 2);
    ::execv(KILN_CLI, argv.data());
    ::_exit(127);
  }
  int status = 0;
  rusage usage{};
  ::wait4(child, &status, 0, &usage);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) return -1;
  return static_cast<long long>(usage.ru_maxrss) * 1024;
}

// The bunny at 1024^3 holds 3.6 M surface cells: 29 MB of codes, twice that while the voxelizer
// concatenates its bricks. Under a 16 MiB budget the cubes are 128^3 and the build's peak stays
// within the budget plus a stated slack over the process baseline (import and the output).
TEST(EsvoCubes, SmallBudgetBoundsThePeak) {
  KILN_REQUIRE_CORPUS();
  if (test::kSanitized)
    GTEST_SKIP() << "resident sizes under AddressSanitizer are its own: skipped";
  TempDir dir;
  const std::string mesh = mesh_path("stanford/stanford-bunny.obj.zst");
  const auto peak = [&](const std::string& resolution, const std::string& budget) {
    return cli_peak_bytes({"build", mesh, "--accel", "esvo", "--resolution", resolution,
                           "--memory-budget", budget, "--threads", "2", "-o", dir.file("e.kiln")});
  };
  const long long baseline = peak("8", "16M");
  const long long cubes = peak("1024", "16M");
  const long long whole = peak("1024", "1T");
  ASSERT_GT(baseline, 0);
  ASSERT_GT(cubes, 0);
  ASSERT_GT(whole, 0);
  constexpr long long kMiB = 1 << 20;
  constexpr long long kSlack = 24 * kMiB;  // the 4.5 MB blob, its tree before layout, scratch
  std::cout << "peak over the baseline: cubes " << (cubes - baseline) / kMiB << " MiB, whole grid "
            << (whole - baseline) / kMiB << " MiB\n";
  EXPECT_LE(cubes, baseline + 16 * kMiB + kSlack);
  EXPECT_GT(whole - cubes, 24 * kMiB);  // the codes the whole-grid build holds at once
}

TEST(EsvoCubes, BadBudgetsAreRefused) {
  KILN_REQUIRE_CORPUS();
  TempDir dir;
  const std::string mesh = quoted(mesh_path("stanford/stanford-bunny.obj.zst"));
  for (const std::string bad : {"0", "8Q", "-1", "G", "99999999999T"}) {
    const CommandResult r = run_kiln("build " + mesh + " --accel esvo --resolution 64 " +
                                     "--memory-budget " + bad + " -o " + quoted(dir.file("x")));
    EXPECT_NE(r.exit_code, 0) << bad;
    EXPECT_EQ(r.signal, 0) << bad;
    EXPECT_NE(r.err.find("memory-budget"), std::string::npos) << bad << ": " << r.err;
  }
  for (const std::string good : {"64M", "1g", "512MiB", "100000000", "auto"}) {
    const CommandResult r = run_kiln("build " + mesh + " --accel esvo --resolution 64 " +
                                     "--memory-budget " + good + " -o " + quoted(dir.file("x")));
    EXPECT_EQ(r.exit_code, 0) << good << ": " << r.err;
  }
}

}  // namespace
}  // namespace kiln
