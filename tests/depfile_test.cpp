// `kiln build --depfile`: every file the import read, in the syntax Make, Ninja and CMake read.
#include <filesystem>
#include <string>
#include <vector>

#include "import_fixtures.hpp"
#include "kiln/compiler/depfile.hpp"
#include "kiln/compiler/import.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

namespace fs = std::filesystem;

using test::quoted;
using test::read_text;
using test::write_gltf_with_bin;
using test::write_obj_with_mtl;
using test::write_text;

// The target and dependencies of a depfile as format_depfile lays it out, unescaped the way
// Make and Ninja read it ("\ " is a space in a name, "\#" a '#', "$$" a '$').
struct ParsedDepfile {
  std::string target;
  std::vector<std::string> dependencies;
};

std::string unescape(const std::string& word) {
  std::string out;
  for (std::size_t i = 0; i < word.size(); ++i) {
    if (word[i] == '\\' && i + 1 < word.size() && (word[i + 1] == ' ' || word[i + 1] == '#'))
      ++i;
    else if (word[i] == '$' && i + 1 < word.size() && word[i + 1] == '$')
      ++i;
    out += word[i];
  }
  return out;
}

ParsedDepfile parse_depfile(const std::string& text) {
  ParsedDepfile parsed;
  std::vector<std::string> lines;
  std::size_t start = 0;
  for (std::size_t end; (end = text.find('\n', start)) != std::string::npos; start = end + 1)
    lines.push_back(text.substr(start, end - start));
  EXPECT_EQ(start, text.size()) << "the depfile must end with a newline";
  if (lines.empty()) return parsed;
  auto strip_continuation = [](std::string& line, bool last) {
    if (last) return;
    EXPECT_TRUE(line.size() >= 2 && line.ends_with(" \\")) << line;
    line.resize(line.size() - 2);
  };
  std::string first = lines[0];
  strip_continuation(first, lines.size() == 1);
  EXPECT_TRUE(first.ends_with(":")) << first;
  parsed.target = unescape(first.substr(0, first.size() - 1));
  for (std::size_t i = 1; i < lines.size(); ++i) {
    std::string line = lines[i];
    strip_continuation(line, i + 1 == lines.size());
    EXPECT_TRUE(line.starts_with("  ")) << line;
    parsed.dependencies.push_back(unescape(line.substr(2)));
  }
  return parsed;
}

std::string absolute_path(const fs::path& path) {
  return fs::absolute(path).lexically_normal().string();
}

// Changes the working directory for one scope (relative -o paths).
class CurrentDirectory {
 public:
  explicit CurrentDirectory(const fs::path& dir) : previous_(fs::current_path()) {
    fs::current_path(dir);
  }
  ~CurrentDirectory() { fs::current_path(previous_); }

 private:
  fs::path previous_;
};

TEST(Depfile, EscapesWhatMakeAndNinjaWouldSplitOrExpand) {
  EXPECT_EQ(escape_depfile_path("/a b/c#d$e:f"), "/a\\ b/c\\#d$$e:f");
  EXPECT_EQ(escape_depfile_path("tab\there"), "tab\\\there");
  // A backslash right before a blank is doubled: Make reads 2N+1 of them as N and a blank.
  EXPECT_EQ(escape_depfile_path("x\\ y"), "x\\\\\\ y");
  EXPECT_EQ(escape_depfile_path("x\\y"), "x\\y");
  EXPECT_THROW(escape_depfile_path("new\nline"), DepfileError);
  EXPECT_THROW(escape_depfile_path("cr\rx"), DepfileError);
  EXPECT_THROW(escape_depfile_path("trailing\\"), DepfileError);
  EXPECT_THROW(escape_depfile_path(""), DepfileError);
  const std::vector<std::string> deps = {"/m/a.obj", "/m/a b.mtl"};
  EXPECT_EQ(format_depfile("out dir/x.kiln", deps),
            "out\\ dir/x.kiln: \\\n  /m/a.obj \\\n  /m/a\\ b.mtl\n");
  EXPECT_EQ(format_depfile("x.kiln", {}), "x.kiln:\n");
}

TEST(Depfile, ImportRecordsAnObjsMtlAndTheMtlItDidNotFind) {
  test::TempDir dir;
  write_obj_with_mtl(dir.path(), "mesh.mtl", "1 0 0");
  const ImportedFile found = import_file(dir.file("mesh.obj"));
  EXPECT_EQ(found.accessed.read,
            (std::vector<std::string>{absolute_path(dir.path() / "mesh.mtl"),
                                      absolute_path(dir.path() / "mesh.obj")}));
  EXPECT_TRUE(found.accessed.missing.empty());

  fs::remove(dir.path() / "mesh.mtl");
  const ImportedFile lost = import_file(dir.file("mesh.obj"));
  EXPECT_EQ(lost.accessed.read, std::vector<std::string>{absolute_path(dir.path() / "mesh.obj")});
  // The build cache must see it still absent: creating it would colour the mesh.
  EXPECT_NE(std::find(lost.accessed.missing.begin(), lost.accessed.missing.end(),
                      absolute_path(dir.path() / "mesh.mtl")),
            lost.accessed.missing.end());
}

TEST(Depfile, ObjWithMtlListsBothUnderAFolderWithSpaces) {
  test::TempDir temp;
  const fs::path dir = temp.path() / "my meshes #1";
  fs::create_directories(dir);
  write_obj_with_mtl(dir, "mesh.mtl", "1 0 0");
  const std::string blob = temp.file("out.kiln"), depfile = temp.file("out.d");
  const auto result = test::run_kiln("build " + quoted((dir / "mesh.obj").string()) + " -o " +
                                     quoted(blob) + " --depfile " + quoted(depfile));
  ASSERT_EQ(result.exit_code, 0) << result.err;
  const std::string text = read_text(depfile);
  const ParsedDepfile parsed = parse_depfile(text);
  EXPECT_EQ(parsed.target, blob);
  EXPECT_EQ(parsed.dependencies, (std::vector<std::string>{absolute_path(dir / "mesh.mtl"),
                                                           absolute_path(dir / "mesh.obj")}));
  EXPECT_NE(text.find("my\\ meshes\\ \\#1/mesh.mtl"), std::string::npos) << text;
}

TEST(Depfile, CorpusObjListsItsMtl) {
  KILN_REQUIRE_CORPUS();
  test::TempDir dir;
  const std::string obj = test::mesh_path("assimp/OBJ/spider.obj");
  const auto result = test::run_kiln("build " + quoted(obj) + " -o " + quoted(dir.file("s.kiln")) +
                                     " --depfile " + quoted(dir.file("s.d")));
  ASSERT_EQ(result.exit_code, 0) << result.err;
  const ParsedDepfile parsed = parse_depfile(read_text(dir.file("s.d")));
  EXPECT_EQ(parsed.dependencies,
            (std::vector<std::string>{absolute_path(test::mesh_path("assimp/OBJ/spider.mtl")),
                                      absolute_path(obj)}));
}

TEST(Depfile, GltfListsItsExternalBufferButNotItsImage) {
  test::TempDir dir;
  write_gltf_with_bin(dir.path(), "tri.bin", 1.0f);
  const auto result =
      test::run_kiln("build " + quoted(dir.file("mesh.gltf")) + " -o " +
                     quoted(dir.file("tri.kiln")) + " --depfile " + quoted(dir.file("tri.d")));
  ASSERT_EQ(result.exit_code, 0) << result.err;
  const ParsedDepfile parsed = parse_depfile(read_text(dir.file("tri.d")));
  // Images are never opened (TINYGLTF_NO_EXTERNAL_IMAGE): they do not shape the blob.
  EXPECT_EQ(parsed.dependencies, (std::vector<std::string>{absolute_path(dir.path() / "mesh.gltf"),
                                                           absolute_path(dir.path() / "tri.bin")}));
}

TEST(Depfile, CorpusDracoGltfListsItsBin) {
  KILN_REQUIRE_CORPUS();
  test::TempDir dir;
  const std::string gltf = test::mesh_path("gltf/2CylinderEngine-glTF-Draco/2CylinderEngine.gltf");
  const auto result =
      test::run_kiln("build " + quoted(gltf) + " " + quoted(test::mesh_path("classic/teapot.obj")) +
                     " -o " + quoted(dir.file("e.kiln")) + " --depfile " + quoted(dir.file("e.d")));
  ASSERT_EQ(result.exit_code, 0) << result.err;
  const ParsedDepfile parsed = parse_depfile(read_text(dir.file("e.d")));
  EXPECT_EQ(
      parsed.dependencies,
      (std::vector<std::string>{
          absolute_path(test::mesh_path("classic/teapot.obj")),
          absolute_path(test::mesh_path("gltf/2CylinderEngine-glTF-Draco/2CylinderEngine.bin")),
          absolute_path(gltf)}));
}

TEST(Depfile, TargetIsTheOutputExactlyAsGiven) {
  test::TempDir dir;
  write_obj_with_mtl(dir.path(), "mesh.mtl", "1 0 0");
  fs::create_directories(dir.path() / "out");
  const CurrentDirectory cwd(dir.path());
  const auto result =
      test::run_kiln("build mesh.obj -o ./out/../out/m.kiln --depfile out/m.kiln.d");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  const ParsedDepfile parsed = parse_depfile(read_text(dir.path() / "out/m.kiln.d"));
  EXPECT_EQ(parsed.target, "./out/../out/m.kiln");
  // Dependencies are absolute whatever the inputs' spelling.
  EXPECT_EQ(parsed.dependencies,
            (std::vector<std::string>{absolute_path(dir.path() / "mesh.mtl"),
                                      absolute_path(dir.path() / "mesh.obj")}));
}

TEST(Depfile, FailedBuildWritesNeitherDepfileNorBlob) {
  test::TempDir dir;
  write_gltf_with_bin(dir.path(), "tri.bin", 1.0f);
  fs::remove(dir.path() / "tri.bin");  // the buffer is missing: the import fails
  const auto result =
      test::run_kiln("build " + quoted(dir.file("mesh.gltf")) + " -o " +
                     quoted(dir.file("tri.kiln")) + " --depfile " + quoted(dir.file("tri.d")));
  EXPECT_EQ(result.exit_code, 1) << result.err;
  EXPECT_FALSE(fs::exists(dir.file("tri.d")));
  EXPECT_FALSE(fs::exists(dir.file("tri.kiln")));

  write_text(dir.path() / "empty.obj", "");
  const auto empty =
      test::run_kiln("build " + quoted(dir.file("empty.obj")) + " -o " +
                     quoted(dir.file("e.kiln")) + " --depfile " + quoted(dir.file("e.d")));
  EXPECT_EQ(empty.exit_code, 1);
  EXPECT_FALSE(fs::exists(dir.file("e.d")));
  EXPECT_FALSE(fs::exists(dir.file("e.kiln")));
}

TEST(Depfile, RefusesToOverwriteTheBlobOrAnInput) {
  test::TempDir dir;
  write_obj_with_mtl(dir.path(), "mesh.mtl", "1 0 0");
  const std::string obj = quoted(dir.file("mesh.obj"));
  EXPECT_EQ(test::run_kiln("build " + obj + " -o " + quoted(dir.file("m.kiln")) + " --depfile " +
                           quoted(dir.file("m.kiln")))
                .exit_code,
            2);
  EXPECT_EQ(
      test::run_kiln("build " + obj + " -o " + quoted(dir.file("m.kiln")) + " --depfile " + obj)
          .exit_code,
      2);
  EXPECT_EQ(read_text(dir.path() / "mesh.obj").substr(0, 6), "mtllib");
}

}  // namespace
}  // namespace kiln
