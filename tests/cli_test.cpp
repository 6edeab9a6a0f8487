// The command line as users and CI run it.
#include <cmath>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "kiln/formats/container.hpp"
#include "kiln/runtime/checksum.hpp"
#include "kiln/runtime/ray.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

namespace fs = std::filesystem;

using test::quoted;

TEST(Cli, EveryCommandHasHelp) {
  for (const char* command : {"--help", "build --help", "dump --help", "verify --help",
                              "trace --help", "rays --help", "query --help"}) {
    const auto result = test::run_kiln(command);
    EXPECT_EQ(result.exit_code, 0) << command;
    EXPECT_NE(result.out.find("Usage"), std::string::npos) << command;
  }
}

TEST(Cli, BuildThenDumpJsonReportsTheTriangleCount) {
  KILN_REQUIRE_CORPUS();
  test::TempDir dir;
  const std::string blob = dir.file("engine.kiln");
  const std::string input = test::mesh_path("gltf/2CylinderEngine-glTF-Binary/2CylinderEngine.glb");
  ASSERT_EQ(test::run_kiln("build " + quoted(input) + " -o " + quoted(blob)).exit_code, 0);
  const auto dump = test::run_kiln("dump --json " + quoted(blob));
  ASSERT_EQ(dump.exit_code, 0) << dump.err;
  const auto json = nlohmann::json::parse(dump.out);
  EXPECT_EQ(json["manifest"]["scene"]["triangle_count"], 110336);
  EXPECT_EQ(json["manifest"]["scene"]["input_triangle_count"], 121496);
  EXPECT_EQ(json["manifest"]["scene"]["degenerate_triangles_dropped"], 11160);
  EXPECT_EQ(json["manifest"]["sources"][0]["path"], input);
  EXPECT_EQ(json["sections"][0]["kind"], "MANI");
  EXPECT_EQ(json["header"]["file_size"], fs::file_size(blob));

  const auto human = test::run_kiln("dump " + quoted(blob));
  EXPECT_EQ(human.exit_code, 0);
  EXPECT_NE(human.out.find("110336"), std::string::npos);
  EXPECT_EQ(test::run_kiln("verify " + quoted(blob)).exit_code, 0);
}

TEST(Cli, ThreadCountDoesNotChangeTheBlob) {
  KILN_REQUIRE_CORPUS();
  test::TempDir dir;
  const std::string inputs = quoted(test::mesh_path("stanford/bun_zipper.ply.zst")) + " " +
                             quoted(test::mesh_path("classic/spot.obj"));
  for (const char* extra : {"", " --compress"}) {
    ASSERT_EQ(test::run_kiln("build " + inputs + " -o " + quoted(dir.file("a.kiln")) +
                             " --threads 1" + extra)
                  .exit_code,
              0);
    ASSERT_EQ(test::run_kiln("build " + inputs + " -o " + quoted(dir.file("b.kiln")) +
                             " --threads 2" + extra)
                  .exit_code,
              0);
    EXPECT_EQ(test::read_file(dir.file("a.kiln")), test::read_file(dir.file("b.kiln"))) << extra;
  }
}

TEST(Cli, VerifyRejectsTruncatedAndFlippedBlobsWithOneLine) {
  KILN_REQUIRE_CORPUS();
  test::TempDir dir;
  const std::string blob = dir.file("teapot.kiln");
  ASSERT_EQ(test::run_kiln("build " + quoted(test::mesh_path("classic/teapot.obj")) + " -o " +
                           quoted(blob))
                .exit_code,
            0);
  auto bytes = test::read_file(blob);

  const std::string truncated = dir.file("truncated.kiln");
  test::write_file(truncated, std::span<const std::byte>(bytes).first(bytes.size() / 2));
  auto result = test::run_kiln("verify " + quoted(truncated));
  EXPECT_NE(result.exit_code, 0);
  EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << result.err;
  EXPECT_NE(result.err.find("truncated"), std::string::npos) << result.err;

  const std::string flipped = dir.file("flipped.kiln");
  bytes[bytes.size() - 100] ^= std::byte{0x04};  // inside the last section's payload
  test::write_file(flipped, bytes);
  result = test::run_kiln("verify " + quoted(flipped));
  EXPECT_NE(result.exit_code, 0);
  EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << result.err;
  EXPECT_NE(result.err.find("checksum"), std::string::npos) << result.err;
  EXPECT_EQ(test::run_kiln("dump " + quoted(flipped)).exit_code, 0);  // open does not hash payloads

  result = test::run_kiln("verify --json " + quoted(flipped));
  EXPECT_FALSE(nlohmann::json::parse(result.out)["ok"].get<bool>());
}

TEST(Cli, AbsurdOptionsAreRefused) {
  KILN_REQUIRE_CORPUS();
  test::TempDir dir;
  const std::string input = quoted(test::mesh_path("assimp/OBJ/box.obj"));
  for (const char* options :
       {"--threads 100000", "--threads -3", "--compression-level 99", "--bogus"}) {
    const auto result =
        test::run_kiln("build " + input + " -o " + quoted(dir.file("x.kiln")) + " " + options);
    EXPECT_NE(result.exit_code, 0) << options;
    EXPECT_FALSE(fs::exists(dir.file("x.kiln"))) << options;
  }
  const auto missing_output = test::run_kiln("build " + input);
  EXPECT_NE(missing_output.exit_code, 0);
  const auto same_file = test::run_kiln("build " + input + " -o " + input);
  EXPECT_NE(same_file.exit_code, 0);
}

struct HitRecord {
  float t;
  std::uint32_t prim;
  float u, v;
};

std::vector<HitRecord> read_hits(const std::string& path) {
  const auto bytes = test::read_file(path);
  std::vector<HitRecord> hits(bytes.size() / sizeof(HitRecord));
  std::memcpy(hits.data(), bytes.data(), hits.size() * sizeof(HitRecord));
  return hits;
}

TEST(Cli, BuildRaysTraceWithBothBvhs) {
  KILN_REQUIRE_CORPUS();
  test::TempDir dir;
  const std::string blob = dir.file("x.kiln");
  const std::string mesh = quoted(test::mesh_path("stanford/Lucy100k.ply"));
  ASSERT_EQ(
      test::run_kiln("build --accel bvh --accel sbvh " + mesh + " -o " + quoted(blob)).exit_code,
      0);
  const auto dump = nlohmann::json::parse(test::run_kiln("dump --json " + quoted(blob)).out);
  ASSERT_EQ(dump["manifest"]["structures"].size(), 2u);
  EXPECT_EQ(dump["manifest"]["structures"][1]["kind"], "sbvh");
  EXPECT_GE(dump["manifest"]["structures"][1]["sbvh"]["reference_count"].get<std::uint64_t>(),
            100000u);
  EXPECT_EQ(test::run_kiln("verify " + quoted(blob)).exit_code, 0);

  for (const char* kind : {"primary", "diffuse", "shadow"}) {
    SCOPED_TRACE(kind);
    const std::string rays = dir.file(std::string(kind) + ".rays");
    ASSERT_EQ(test::run_kiln("rays " + quoted(blob) + " --kind " + kind +
                             " --count 5000 --seed 3 -o " + quoted(rays))
                  .exit_code,
              0);
    EXPECT_EQ(fs::file_size(rays), 5000u * 32u);
    // Reproducible, whatever the thread count.
    ASSERT_EQ(test::run_kiln("rays " + quoted(blob) + " --kind " + kind +
                             " --count 5000 --seed 3 --threads 1 -o " + quoted(rays + "2"))
                  .exit_code,
              0);
    EXPECT_EQ(test::read_file(rays), test::read_file(rays + "2"));

    const std::string a = dir.file("a.hits"), b = dir.file("b.hits"), any = dir.file("any.hits");
    ASSERT_EQ(test::run_kiln("trace " + quoted(blob) + " --accel bvh --rays " + quoted(rays) +
                             " --out " + quoted(a))
                  .exit_code,
              0);
    ASSERT_EQ(test::run_kiln("trace " + quoted(blob) + " --accel sbvh --threads 1 --rays " +
                             quoted(rays) + " --out " + quoted(b))
                  .exit_code,
              0);
    ASSERT_EQ(test::run_kiln("trace " + quoted(blob) + " --any-hit --rays " + quoted(rays) +
                             " --out " + quoted(any))
                  .exit_code,
              0);
    const auto ha = read_hits(a), hb = read_hits(b), hany = read_hits(any);
    ASSERT_EQ(ha.size(), 5000u);
    ASSERT_EQ(hb.size(), 5000u);
    std::size_t hits = 0;
    for (std::size_t i = 0; i < ha.size(); ++i) {
      ASSERT_EQ(ha[i].prim == 0xFFFFFFFFu, hb[i].prim == 0xFFFFFFFFu) << i;
      ASSERT_EQ(ha[i].prim == 0xFFFFFFFFu, hany[i].prim == 0xFFFFFFFFu) << i;
      if (ha[i].prim == 0xFFFFFFFFu) {
        EXPECT_TRUE(std::isinf(ha[i].t));
        continue;
      }
      ++hits;
      EXPECT_EQ(ha[i].t, hb[i].t) << i;
      EXPECT_GE(hany[i].t, ha[i].t) << i;
    }
    EXPECT_GT(hits, 0u);
  }
}

// `kiln rays --camera`: primary rays start at the eye and look towards the target; diffuse rays
// start on the surface; a malformed camera is refused in one line. `--bvh-width` and
// `--bvh-boxes` reach the blob's description.
TEST(Cli, RaysFromACameraAndBvhLayoutFlags) {
  KILN_REQUIRE_CORPUS();
  test::TempDir dir;
  const std::string mesh = quoted(test::mesh_path("classic/teapot.obj"));
  const std::string blob = dir.file("w.kiln");
  ASSERT_EQ(test::run_kiln("build --accel bvh --bvh-width 4 --bvh-boxes u8 " + mesh + " -o " +
                           quoted(blob))
                .exit_code,
            0);
  const auto dump = nlohmann::json::parse(test::run_kiln("dump --json " + quoted(blob)).out);
  EXPECT_EQ(dump["manifest"]["structures"][0]["bvh"]["width"], 4);
  EXPECT_EQ(dump["manifest"]["structures"][0]["bvh"]["quantized"], true);
  const std::string rays = dir.file("c.rays");
  ASSERT_EQ(test::run_kiln("rays " + quoted(blob) + " --count 64 --camera=0.5,1,6,0,0.5,0,40 -o " +
                           quoted(rays))
                .exit_code,
            0);
  const auto bytes = test::read_file(rays);
  ASSERT_EQ(bytes.size(), 64u * sizeof(Ray));
  for (std::size_t i = 0; i < 64; ++i) {
    Ray r;
    std::memcpy(&r, bytes.data() + i * sizeof r, sizeof r);
    EXPECT_EQ(r.org.x, 0.5f);
    EXPECT_EQ(r.org.z, 6.0f);
    EXPECT_LT(r.dir.z, 0.0f);  // towards the target
  }
  ASSERT_EQ(test::run_kiln("rays " + quoted(blob) +
                           " --kind diffuse --count 64 "
                           "--camera=0.5,1,6,0,0.5,0,40 -o " +
                           quoted(rays))
                .exit_code,
            0);
  const auto bad = test::run_kiln("rays " + quoted(blob) + " --camera=1,2,3 -o " + quoted(rays));
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("--camera"), std::string::npos) << bad.err;
}

TEST(Cli, TraceRefusesBadInputs) {
  KILN_REQUIRE_CORPUS();
  test::TempDir dir;
  const std::string blob = dir.file("x.kiln"), plain = dir.file("plain.kiln");
  const std::string mesh = quoted(test::mesh_path("classic/teapot.obj"));
  ASSERT_EQ(test::run_kiln("build --accel bvh " + mesh + " -o " + quoted(blob)).exit_code, 0);
  ASSERT_EQ(test::run_kiln("build " + mesh + " -o " + quoted(plain)).exit_code, 0);
  const std::string rays = dir.file("r.rays");
  ASSERT_EQ(test::run_kiln("rays " + mesh + " --count 100 -o " + quoted(rays)).exit_code, 0);
  auto bytes = test::read_file(rays);
  bytes.resize(bytes.size() - 5);
  const std::string ragged = dir.file("ragged.rays");
  test::write_file(ragged, bytes);

  auto result = test::run_kiln("trace " + quoted(blob) + " --rays " + quoted(ragged) + " --out " +
                               quoted(dir.file("h")));
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.err.find("multiple of 32"), std::string::npos) << result.err;
  EXPECT_FALSE(fs::exists(dir.file("h")));
  result = test::run_kiln("trace " + quoted(blob) + " --accel sbvh --rays " + quoted(rays) +
                          " --out " + quoted(dir.file("h")));
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.err.find("'sbvh'"), std::string::npos) << result.err;
  result = test::run_kiln("trace " + quoted(plain) + " --rays " + quoted(rays) + " --out " +
                          quoted(dir.file("h")));
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.err.find("holds no structure that can trace rays"), std::string::npos)
      << result.err;
  EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << result.err;
  // Two structures of one name, an unknown kind, a bad option value: one line each, no blob.
  for (const char* accels : {"--accel bvh --accel bvh", "--accel bogus", "--accel bvh:max-leaf=0",
                             "--accel bvh:bogus=1"}) {
    result = test::run_kiln("build " + std::string(accels) + " " + mesh + " -o " +
                            quoted(dir.file("y.kiln")));
    EXPECT_EQ(result.exit_code, 1) << accels;
    EXPECT_EQ(result.err.rfind("kiln build: ", 0), 0u) << accels << ": " << result.err;
    EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << result.err;
    EXPECT_FALSE(fs::exists(dir.file("y.kiln"))) << accels;
  }
}

// A tetrahedron as OBJ text: a mesh for the tests that need no corpus.
std::string write_tetrahedron(const test::TempDir& dir) {
  const std::string path = dir.file("tetrahedron.obj");
  test::write_text(path,
                   "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n");
  return path;
}

TEST(Cli, StructuresOfOneKindAreNamedApart) {
  test::TempDir dir;
  const std::string mesh = quoted(write_tetrahedron(dir)), blob = dir.file("x.kiln");
  const auto build =
      test::run_kiln("build --stats --accel bvh:name=a --accel bvh:name=b,max-leaf=2 " + mesh +
                     " -o " + quoted(blob));
  ASSERT_EQ(build.exit_code, 0) << build.err;
  EXPECT_NE(build.err.find("kiln build: a (bvh): built in "), std::string::npos) << build.err;
  EXPECT_NE(build.err.find("kiln build: b (bvh): built in "), std::string::npos) << build.err;
  const auto human = test::run_kiln("dump " + quoted(blob));
  ASSERT_EQ(human.exit_code, 0) << human.err;
  EXPECT_NE(human.out.find("\nstructures\n  a (bvh)\n"), std::string::npos) << human.out;
  EXPECT_NE(human.out.find("\n  b (bvh)\n"), std::string::npos) << human.out;
  const auto dump = test::run_kiln("dump --json " + quoted(blob));
  ASSERT_EQ(dump.exit_code, 0) << dump.err;
  const auto structures = nlohmann::json::parse(dump.out)["manifest"]["structures"];
  ASSERT_EQ(structures.size(), 2u);
  EXPECT_EQ(structures[0]["name"], "a");
  EXPECT_EQ(structures[1]["name"], "b");
  EXPECT_EQ(structures[0]["kind"], "bvh");
  EXPECT_EQ(structures[1]["kind"], "bvh");
  EXPECT_EQ(structures[0]["bvh"]["max_leaf_size"], 8);
  EXPECT_EQ(structures[1]["bvh"]["max_leaf_size"], 2);

  const std::string rays = dir.file("r.rays"), hits = dir.file("b.hits");
  ASSERT_EQ(test::run_kiln("rays " + mesh + " --count 100 -o " + quoted(rays)).exit_code, 0);
  const auto trace = test::run_kiln("trace " + quoted(blob) + " --accel b --rays " + quoted(rays) +
                                    " --out " + quoted(hits));
  ASSERT_EQ(trace.exit_code, 0) << trace.err;
  EXPECT_NE(trace.err.find(" on b,"), std::string::npos) << trace.err;
  EXPECT_EQ(fs::file_size(hits), 100u * 16u);
}

// A format 1.x header (with valid checksums) is refused with the advice to rebuild.
TEST(Cli, FormatOneBlobAsksForARebuild) {
  test::TempDir dir;
  const std::string blob = dir.file("old.kiln");
  ASSERT_EQ(
      test::run_kiln("build " + quoted(write_tetrahedron(dir)) + " -o " + quoted(blob)).exit_code,
      0);
  auto bytes = test::read_file(blob);
  format::FileHeader h;
  std::memcpy(&h, bytes.data(), sizeof h);
  h.version_major = 1;
  std::memcpy(bytes.data(), &h, sizeof h);
  h.header_checksum = xxh3_64(std::span<const std::byte>(bytes).first(56));
  std::memcpy(bytes.data(), &h, sizeof h);
  test::write_file(blob, bytes);
  const auto result = test::run_kiln("dump " + quoted(blob));
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << result.err;
  EXPECT_NE(result.err.find("rebuild"), std::string::npos) << result.err;
}

TEST(Cli, QueryClosestInsideBox) {
  KILN_REQUIRE_CORPUS();
  test::TempDir dir;
  const std::string blob = dir.file("box.kiln");
  ASSERT_EQ(test::run_kiln("build --accel sbvh " + quoted(test::mesh_path("assimp/OBJ/box.obj")) +
                           " -o " + quoted(blob))
                .exit_code,
            0);
  // box.obj is the cube [-0.5, 0.5]^3.
  const float points[] = {0, 0, 0, 2, 0, 0, 0.4f, 0.1f, -0.2f};
  const std::string in = dir.file("points.bin");
  test::write_file(in, std::as_bytes(std::span(points)));
  ASSERT_EQ(test::run_kiln("query " + quoted(blob) + " --op closest --in " + quoted(in) +
                           " --out " + quoted(dir.file("c.bin")))
                .exit_code,
            0);
  const auto closest = test::read_file(dir.file("c.bin"));
  ASSERT_EQ(closest.size(), 3u * 20u);
  float d[3];
  for (int i = 0; i < 3; ++i) std::memcpy(&d[i], closest.data() + 20 * i, 4);
  EXPECT_FLOAT_EQ(d[0], 0.5f);
  EXPECT_FLOAT_EQ(d[1], 1.5f);
  EXPECT_NEAR(d[2], 0.1f, 1e-6f);
  ASSERT_EQ(test::run_kiln("query " + quoted(blob) + " --op inside --in " + quoted(in) + " --out " +
                           quoted(dir.file("i.bin")))
                .exit_code,
            0);
  const auto inside = test::read_file(dir.file("i.bin"));
  ASSERT_EQ(inside.size(), 3u);
  EXPECT_EQ(inside[0], std::byte{1});
  EXPECT_EQ(inside[1], std::byte{0});
  EXPECT_EQ(inside[2], std::byte{1});

  const float boxes[] = {0.45f, -0.1f, -0.1f, 0.6f, 0.1f, 0.1f,   // touches the +x face only
                         -0.1f, -0.1f, -0.1f, 0.1f, 0.1f, 0.1f};  // inside, touches nothing
  const std::string box_in = dir.file("boxes.bin");
  test::write_file(box_in, std::as_bytes(std::span(boxes)));
  ASSERT_EQ(test::run_kiln("query " + quoted(blob) + " --op box --in " + quoted(box_in) +
                           " --out " + quoted(dir.file("b.bin")))
                .exit_code,
            0);
  const auto ids = test::read_file(dir.file("b.bin"));
  std::uint32_t first_count = 0, second_count = 0;
  std::memcpy(&first_count, ids.data(), 4);
  EXPECT_EQ(first_count, 2u);  // the two triangles of the +x face
  std::memcpy(&second_count, ids.data() + 4 + 4 * first_count, 4);
  EXPECT_EQ(second_count, 0u);
  EXPECT_EQ(ids.size(), 4u + 4u * first_count + 4u);

  auto result = test::run_kiln("query " + quoted(blob) + " --op box --in " + quoted(in) +
                               " --out " + quoted(dir.file("x.bin")));
  EXPECT_EQ(result.exit_code, 1);  // 36 bytes is not a whole number of boxes
  EXPECT_NE(result.err.find("multiple of 24"), std::string::npos) << result.err;
  result = test::run_kiln("query " + quoted(blob) + " --op knn --k 4 --in " + quoted(in) +
                          " --out " + quoted(dir.file("x.bin")));
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_FALSE(fs::exists(dir.file("x.bin")));
}

}  // namespace
}  // namespace kiln
