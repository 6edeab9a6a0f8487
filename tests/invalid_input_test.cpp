// Broken meshes: a clear one-line error naming the file and a non-zero exit, never a crash and
// never an output file.
#include <filesystem>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/import.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

namespace fs = std::filesystem;

std::vector<std::string> files_under(const std::string& relative) {
  std::vector<std::string> files;
  for (const auto& entry : fs::recursive_directory_iterator(test::mesh_path(relative)))
    if (entry.is_regular_file()) files.push_back(entry.path().string());
  std::sort(files.begin(), files.end());
  return files;
}

// Assimp's own invalid/ folder (readme.txt included: it is not a mesh either). malformed2.obj
// is the one exception: its only fault is a reference to a material that does not exist, which
// a geometry compiler rightly ignores (the folder's readme asks only that loaders not crash).
TEST(InvalidInput, AssimpInvalidFolderGivesErrorsAndNoOutput) {
  KILN_REQUIRE_CORPUS();
  test::TempDir dir;
  std::size_t checked = 0;
  for (const auto& file : files_under("invalid/assimp-invalid")) {
    SCOPED_TRACE(file);
    const std::string output = dir.file("out.kiln");
    const auto result = test::run_kiln("build '" + file + "' -o '" + output + "'");
    EXPECT_EQ(result.signal, 0);
    if (fs::path(file).filename() == "malformed2.obj") {
      EXPECT_EQ(result.exit_code, 0) << result.err;
      fs::remove(output);
      continue;
    }
    EXPECT_EQ(result.exit_code, 1);
    EXPECT_FALSE(fs::exists(output));
    // One line, starting with the tool and naming the file.
    EXPECT_EQ(result.err.find("kiln build: " + file), 0u) << result.err;
    EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << result.err;
    checked += 1;
  }
  EXPECT_GE(checked, 13u);
}

// The other broken files of the corpus (glTF with bad indices, types, buffers, infinities; OFF
// and PLY regressions): refused, or imported into a blob that verifies. Never a crash.
TEST(InvalidInput, OtherBrokenFilesAreRefusedOrSurvive) {
  KILN_REQUIRE_CORPUS();
  test::TempDir dir;
  std::vector<std::string> files = files_under("invalid/glTF2");
  for (const auto& f : files_under("invalid/assimp-OFF")) files.push_back(f);
  for (const auto& f : files_under("invalid/assimp-PLY")) files.push_back(f);
  std::size_t refused = 0;
  for (const auto& file : files) {
    SCOPED_TRACE(file);
    const std::string output = dir.file("out.kiln");
    const auto result = test::run_kiln("build '" + file + "' -o '" + output + "'");
    EXPECT_EQ(result.signal, 0);
    if (result.exit_code == 0) {
      EXPECT_EQ(test::open_and_verify(test::read_file(output)), "");
      fs::remove(output);
    } else {
      EXPECT_EQ(result.exit_code, 1);
      EXPECT_FALSE(fs::exists(output));
      EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << result.err;
      refused += 1;
    }
  }
  EXPECT_GE(refused, 8u);  // index out of range, missing .bin, bad normals, infinities, ...
}

TEST(InvalidInput, SpecificReasonsAreReported) {
  KILN_REQUIRE_CORPUS();
  auto reason = [](const std::string& relative) {
    try {
      import_scene({test::mesh_path(relative)}, 1);
    } catch (const ImportError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(reason("invalid/glTF2/IndexOutOfRange/IndexOutOfRange.gltf").find("out of range"),
            std::string::npos);
  EXPECT_NE(reason("invalid/glTF2/MissingBin/BoxTextured.gltf").find("BoxTextured0.bin"),
            std::string::npos);
  EXPECT_NE(reason("invalid/assimp-invalid/empty.obj").find("empty"), std::string::npos);
  EXPECT_NE(
      reason("invalid/glTF2/BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb").find("degenerate"),
      std::string::npos);
  // Lines alone are no surface; a point cloud imports (for --accel points, point_tree_test.cpp).
  EXPECT_NE(reason("assimp/OBJ/testline.obj").find("no triangles"), std::string::npos);
  EXPECT_EQ(reason("assimp/OBJ/point_cloud.obj"), "no error");
  EXPECT_NE(reason("does/not/exist.obj").find("no such file"), std::string::npos);
}

TEST(InvalidInput, HostileDracoExtensionIsRefused) {
  KILN_REQUIRE_CORPUS();
  // The Draco glTF with its extension pointing at a buffer view that does not exist: tinygltf
  // would index out of range; the pre-check refuses it.
  test::TempDir dir;
  const auto source =
      test::read_file(test::mesh_path("gltf/2CylinderEngine-glTF-Draco/2CylinderEngine.gltf"));
  std::string text(reinterpret_cast<const char*>(source.data()), source.size());
  const std::string needle = "\"KHR_draco_mesh_compression\":{\"bufferView\":";
  auto at = text.find(needle);
  if (at == std::string::npos) {
    // Pretty-printed JSON: find the first bufferView after the extension name.
    at = text.find("KHR_draco_mesh_compression");
    ASSERT_NE(at, std::string::npos);
    at = text.find("\"bufferView\"", at);
    ASSERT_NE(at, std::string::npos);
    const auto colon = text.find(':', at);
    const auto end = text.find_first_of(",}", colon);
    text.replace(colon + 1, end - colon - 1, " 99999");
  } else {
    const auto start = at + needle.size();
    const auto end = text.find_first_of(",}", start);
    text.replace(start, end - start, "99999");
  }
  const std::string path = dir.file("hostile.gltf");
  test::write_file(path, std::as_bytes(std::span(text)));
  std::filesystem::copy_file(test::mesh_path("gltf/2CylinderEngine-glTF-Draco/2CylinderEngine.bin"),
                             dir.file("2CylinderEngine.bin"));
  try {
    import_scene({path}, 1);
    FAIL() << "hostile file imported";
  } catch (const ImportError& e) {
    EXPECT_NE(std::string(e.what()).find("KHR_draco_mesh_compression"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace kiln
