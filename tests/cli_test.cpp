// The command line as users and CI run it.
#include <filesystem>
#include <nlohmann/json.hpp>

#include "test_support.hpp"

namespace kiln {
namespace {

namespace fs = std::filesystem;

std::string quoted(const std::string& s) {
  return "'" + s + "'";
}

TEST(Cli, EveryCommandHasHelp) {
  for (const char* command : {"--help", "build --help", "dump --help", "verify --help"}) {
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

}  // namespace
}  // namespace kiln
