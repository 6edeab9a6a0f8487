// Kiln's OBJ reader (compiler/src/import_obj.cpp): every shared OBJ exactly as the Assimp path
// (Assimp 5.2.5, Triangulate, JoinIdenticalVertices, Kiln's conversion) imports it, accesses to
// the .mtl included; small files written here for each rule, with what Assimp gave for them
// checked too where Assimp is sane; hostile input refused in one line.
#include <zstd.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <initializer_list>
#include <random>
#include <string>
#include <utility>
#include <vector>

#if defined(__SANITIZE_ADDRESS__)
#include <sanitizer/lsan_interface.h>
#endif

#include "kiln/compiler/import.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

// Assimp, the reference here, leaks on some malformed OBJs (LeakSanitizer, inside libassimp):
// its allocations are not Kiln's, so leak checking pauses while it runs.
struct AssimpLeaksIgnored {
#if defined(__SANITIZE_ADDRESS__)
  AssimpLeaksIgnored() {
    __lsan_disable();
  }
  ~AssimpLeaksIgnored() {
    __lsan_enable();
  }
#endif
};

template <class... Args>
std::vector<ImportedMesh> assimp_reference(Args&&... args) {
  [[maybe_unused]] const AssimpLeaksIgnored ignored;  // empty outside ASan builds
  return import_with_assimp(std::forward<Args>(args)...);
}

using Tri = std::array<std::uint32_t, 3>;

std::vector<std::byte> bytes_of(const std::string& text) {
  std::vector<std::byte> out(text.size());
  std::memcpy(out.data(), text.data(), text.size());
  return out;
}

std::vector<Tri> triangles_of(const ImportedMesh& mesh) {
  std::vector<Tri> out;
  for (const auto& t : mesh.triangles) out.push_back({t.v[0], t.v[1], t.v[2]});
  return out;
}

template <class T>
bool same_bits(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

// Both importers' meshes, field by field, floats bit for bit.
void expect_same_meshes(const std::vector<ImportedMesh>& mine,
                        const std::vector<ImportedMesh>& assimp) {
  ASSERT_EQ(mine.size(), assimp.size());
  for (std::size_t m = 0; m < mine.size(); ++m) {
    SCOPED_TRACE("mesh " + std::to_string(m) + " '" + assimp[m].name + "'");
    EXPECT_EQ(mine[m].name, assimp[m].name);
    EXPECT_EQ(mine[m].positions.size(), assimp[m].positions.size());
    EXPECT_TRUE(same_bits(mine[m].positions, assimp[m].positions));
    EXPECT_TRUE(same_bits(mine[m].normals, assimp[m].normals));
    EXPECT_EQ(mine[m].colors, assimp[m].colors);
    EXPECT_EQ(mine[m].triangles.size(), assimp[m].triangles.size());
    EXPECT_TRUE(same_bits(mine[m].triangles, assimp[m].triangles));
    EXPECT_EQ(mine[m].point_cloud, assimp[m].point_cloud);
    EXPECT_EQ(std::memcmp(&mine[m].transform, &assimp[m].transform, sizeof(Matrix4)), 0);
  }
}

// Assimp reads `path` itself: what both record, normalized as import_file does.
void expect_same_import(const std::string& path, const std::vector<std::byte>& bytes,
                        const ImportLimits& limits = {}) {
  FileAccesses mine_accessed, assimp_accessed;
  mine_accessed.read.push_back(path);  // import_bytes records the file itself
  const auto mine = import_obj(path, bytes, true, limits, &mine_accessed);
  const auto assimp = assimp_reference(path, bytes, ".obj", true, limits, &assimp_accessed);
  expect_same_meshes(mine, assimp);
  normalize_accesses(mine_accessed);
  normalize_accesses(assimp_accessed);
  EXPECT_EQ(mine_accessed.read, assimp_accessed.read);
  EXPECT_EQ(mine_accessed.missing, assimp_accessed.missing);
}

std::vector<std::byte> inflate(const std::vector<std::byte>& stored) {
  const auto size = ZSTD_getFrameContentSize(stored.data(), stored.size());
  std::vector<std::byte> out(size);
  const auto got = ZSTD_decompress(out.data(), out.size(), stored.data(), stored.size());
  EXPECT_EQ(got, size);
  return out;
}

// Every OBJ of the corpus outside invalid/: read from their path, the .zst ones (and the UTF-16
// one, transcoded) from memory as import_bytes reads them. From memory Assimp still looked for
// an `mtllib` in the working directory, then read the OBJ itself as the .mtl; Kiln reads no
// companion there, so only the meshes are compared.
TEST(ObjImport, SharedObjsImportAsBefore) {
  KILN_REQUIRE_CORPUS();
  std::vector<std::string> paths;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(test::mesh_path(""))) {
    const std::string path = entry.path().string();
    if (path.find("/invalid/") == std::string::npos &&
        (path.ends_with(".obj") || path.ends_with(".obj.zst")))
      paths.push_back(path);
  }
  std::sort(paths.begin(), paths.end());
  EXPECT_GE(paths.size(), 23u);  // 13 from Assimp, 6 classic, 4 Stanford
  for (const std::string& path : paths) {
    SCOPED_TRACE(path);
    const auto stored = test::read_file(path);
    if (path.ends_with(".zst")) {
      const std::string inner = path.substr(0, path.size() - 4);
      const auto bytes = inflate(stored);
      expect_same_meshes(import_obj(inner, bytes, false, {}),
                         assimp_reference(inner, bytes, ".obj", false, ImportLimits{}));
    } else if (stored.size() > 2 && stored[0] == std::byte{0xFE}) {
      std::vector<std::byte> utf8;  // ASCII in UTF-16BE: every second byte
      for (std::size_t i = 3; i < stored.size(); i += 2) utf8.push_back(stored[i]);
      expect_same_meshes(import_obj(path, utf8, false, {}),
                         assimp_reference(path, utf8, ".obj", false, ImportLimits{}));
    } else {
      expect_same_import(path, stored);
    }
  }
}

// Written into a fresh folder as mesh.obj (and its companions), then imported both ways: the
// same meshes and accesses, or both refused.
struct Case {
  const char* name;
  std::string obj;
  std::vector<std::pair<std::string, std::string>> companions = {};
};

void expect_as_assimp(const Case& c) {
  SCOPED_TRACE(c.name);
  test::TempDir dir;
  const std::string path = dir.file("mesh.obj");
  test::write_text(path, c.obj);
  for (const auto& [name, text] : c.companions) test::write_text(dir.file(name), text);
  const auto bytes = test::read_file(path);
  std::string mine_error, assimp_error;
  try {
    import_obj(path, bytes, true, {});
  } catch (const ImportError& e) {
    mine_error = e.what();
    EXPECT_EQ(mine_error.rfind(path, 0), 0u) << mine_error;
    EXPECT_EQ(mine_error.find('\n'), std::string::npos) << mine_error;
  }
  try {
    assimp_reference(path, bytes, ".obj", true, ImportLimits{});
  } catch (const ImportError& e) {
    assimp_error = e.what();
  }
  EXPECT_EQ(mine_error.empty(), assimp_error.empty())
      << "Kiln: " << mine_error << "\nAssimp: " << assimp_error;
  if (mine_error.empty() && assimp_error.empty()) expect_same_import(path, bytes);
}

const std::string kSquare = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";
const std::string kMtl =
    "newmtl red\nKd 1 0 0\nnewmtl blue\n  Kd 0 0 1\nnewmtl plain\nKd 0.6 0.6 0.6\n"
    "newmtl textured\nmap_Kd -clamp on wood.png\nnewmtl grey\nKd 0.5\nnewmtl dim\nTr 0.5\n";

TEST(ObjImport, SmallFilesImportAsAssimpDid) {
  const Case cases[] = {
      {"negative indices", kSquare + "f -4 -3 -2\nf -4 -2 -1\n"},
      {"forward references", "f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"},
      {"v//vn", kSquare + "vn 0 0 1\nvn 0 0 -1\nf 1//1 2//1 3//1\nf 1//2 3//2 4//2\n"},
      {"v/vt/vn", kSquare + "vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\nf 1/1/1 2/2/1 3/3/1 4/1/1\n"},
      {"v/vt", kSquare + "vt 0 0\nvt 1 1\nf 1/1 2/1 3/2\nf 1/2 3/2 4/2\n"},
      {"continuation", kSquare + "f 1 \\\n2 3\nf 1 3\\\r\n 4\n"},
      {"continuation into an empty line", kSquare + "f 1 2 4 \\\n\nf 2 3 4\n"},
      {"crlf and form feed", "v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\fv 1 1 0\r\nf 1 2 3\r\nf 2 4 3"},
      {"groups and materials",
       "mtllib m.mtl\n" + kSquare +
           "g a\nusemtl red\nf 1 2 3\nusemtl blue\nf 1 3 4\n"
           "g b\nf 1 2 4\nusemtl red\nusemtl red\nf 2 3 4\n"
           "o thing\nusemtl plain\nf 1 2 3\ng a\nusemtl textured\n"
           "f 1 3 4\nusemtl grey\nf 1 2 3\nusemtl dim\nf 2 3 4\n",
       {{"m.mtl", kMtl}}},
      {"usemtl before anything",
       "usemtl red\nmtllib m.mtl\n" + kSquare + "f 1 2 3\n",
       {{"m.mtl", kMtl}}},
      {"library after faces",
       kSquare + "g a\nf 1 2 3\nmtllib m.mtl\nf 1 3 4\ng b\nf 1 2 3\n",
       {{"m.mtl", kMtl}}},
      {"usemtl of an unknown material", kSquare + "usemtl nothing\nf 1 2 3\n"},
      {"missing library", "mtllib absent.mtl\n" + kSquare + "usemtl red\nf 1 2 3\n"},
      {"library by the obj's name",
       "mtllib absent.mtl\n" + kSquare + "usemtl red\nf 1 2 3\n",
       {{"mesh.mtl", kMtl}}},
      {"library in a subfolder",
       "mtllib sub\\m.mtl\n" + kSquare + "usemtl blue\nf 1 2 3\n",
       {{"m.mtl", kMtl}}},
      {"object reused", kSquare + "o a\nf 1 2 3\no b\nf 1 3 4\no a\nf 2 3 4\ng\nf 1 2 3\n"},
      {"empty group name", kSquare + "g\nf 1 2 3\ng x\nf 1 3 4\ng\nf 2 3 4\n"},
      {"cstype", kSquare + "cstype bspline\nf 1 2 3\nend\nf 1 3 4\n"},
      {"indented lines are skipped", kSquare + "  f 1 2 3\n\tv 5 5 5\nf 1 3 4\n"},
      {"out of range", kSquare + "f 1 2 9\n"},
      {"index zero", kSquare + "f 0 1 2\n"},
      {"normal out of range", kSquare + "vn 0 0 1\nf 1//1 2//1 3//7\nf 1//1 3//1 4//1\n"},
      {"uv out of range", kSquare + "vt 0 0\nf 1/1 2/1 3/9\n"},
      {"signs and zeros in indices", kSquare + "f +1 2 3\nf 01 3 004\n"},
      {"a third field without uvs", kSquare + "vn 0 0 1\nf 1/1 2/1 3/1\n"},
      {"not a number", kSquare + "v 1 x 2 3\nf 1 2 3\n"},
      {"vertex of two numbers ignored", "v 9 9\n" + kSquare + "f 1 2 3\n"},
      {"number formats",
       "v 1,5 2.e1 -3.1+e2\nv .5 1 2 3\nv 1e-2 +2 -nan\nv inf 1 2\n"
       "v 99999999999999999999 1 2\nv 0.1234567890123456789 1 1\nf 1 2 3 4\n"},
      {"bare exponent", "v 1e 2 3\nv 0 0 0\nv 1 1 1\nf 1 2 3\n"},
      {"homogeneous", "v 2 4 6 2\nv 0 0 0 1\nv 1 0 0 0.5\nf 1 2 3\n"},
      {"homogeneous w = 0", "v 2 4 6 0\nv 0 0 0\nv 1 0 0\nf 1 2 3\n"},
      {"vertex colours",
       "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nv 0 0 0 0 0 1\n"
       "f 1 2 3\nf 4 2 3\n",
       {}},
      {"vertex colours with a material",
       "mtllib m.mtl\nusemtl grey\nv 0 0 0 1 0 0\n"
       "v 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n",
       {{"m.mtl", kMtl}}},
      {"texture coordinates of one number", kSquare + "vt 1\nf 1 2 3\n"},
      {"texture coordinates of three", kSquare + "vt 1 2 3\nvt nan inf 0\nf 1/1 2/2 3/1\n"},
      {"concave quad", "v 0 0 0\nv 2 0 0\nv 0.5 0.5 0\nv 0 2 0\nf 1 2 3 4\nf 2 3 4 1\n"},
      {"concave pentagon", "v 0 0 0\nv 4 0 0\nv 4 4 0\nv 2 1 0\nv 0 4 0\nf 1 2 3 4 5\n"},
      {"hexagon in yz, reversed",
       "v 0 0 0\nv 0 0 1\nv 0 1 2\nv 0 2 1\nv 0 2 0\nv 0 1 -1\n"
       "f 6 5 4 3 2 1\nf 1 2 3 4 5 6\n"},
      {"self-intersecting polygon",
       "v 0 0 0\nv 2 2 0\nv 2 0 0\nv 0 2 0\nv 1 3 0\nv 1 -1 0\n"
       "f 1 2 3 4 5 6\n"},
      {"lines and points", kSquare + "l 1 2 3 4\np 1 2\nf 1 2 3\nl 3 4\n"},
      {"lines only", kSquare + "l 1 2 3 4 1\n"},
      {"points only", kSquare + "p 1 2 3\n"},
      {"a line of one vertex", kSquare + "f 1 2 3\nl 4\n"},
      {"faces of one and two corners", kSquare + "f 1\nf 1 2\nf 2 3 4\n"},
      {"point cloud", kSquare + "vn 0 0 1\nvn 0 0 1\nvn 0 0 1\nvn 0 1 0\n"},
      {"point cloud short of normals", kSquare + "vn 0 0 1\n"},
      {"vertices in a group", kSquare + "g lonely\n"},
      {"only comments", "# nothing here at all\n# nor here\n"},
      {"mtl: a bad number",
       "mtllib bad.mtl\n" + kSquare + "usemtl x\nf 1 2 3\n",
       {{"bad.mtl", "newmtl x\nKd 0.5 zero 0\n"}}},
      {"mtl: trailing space after Kd",
       "mtllib t.mtl\n" + kSquare + "usemtl x\nf 1 2 3\n",
       {{"t.mtl", "newmtl x\nKd 0.5 \n"}}},
      {"mtl: newmtl alone",
       "mtllib d.mtl\n" + kSquare + "usemtl DefaultMaterial\nf 1 2 3\n",
       {{"d.mtl", "newmtl\nKd 1 1 0\n"}}},
      {"mtl: empty", "mtllib e.mtl\n" + kSquare + "usemtl x\nf 1 2 3\n", {{"e.mtl", ""}}},
      {"mtl: everything",
       "mtllib all.mtl\n" + kSquare + "usemtl a\nf 1 2 3\nusemtl b\nf 2 3 4\n",
       {{"all.mtl",
         "\xEF\xBB\xBFnewmtl a\nKa 0.1 0.2 0.3\nKs 1 1 1\nKe 0 0 0\nNs 10\nNi 1.5\n"
         "d 0.5\nTf 1 1 1\nillum 2\nPr 0.5\nPm\nPs 1 1 1\nPc 1\nPcr 0.2\na 0.1\n"
         "map_Kd a.png\nbump -bm 2 b.png\nnorm n.png\ndisp d.png\nrefl -type sphere "
         "r.png\nnewmtl b\n\tKd 0.25 0.5 0.75\nmap_d\n"}}},
      {"mtl: aniso",
       "mtllib an.mtl\n" + kSquare + "usemtl x\nf 1 2 3\n",
       {{"an.mtl", "newmtl x\naniso 0.5\n"}}},
  };
  for (const Case& c : cases) expect_as_assimp(c);
}

// Files of random statements in every form above (but those where Kiln differs on purpose),
// from a fixed seed: each as Assimp imported or refused it.
class RandomObj {
 public:
  explicit RandomObj(std::uint32_t seed) : random_(seed) {}
  std::string file() {
    std::string text = pick({"", "mtllib m.mtl\n", "usemtl red\n"});
    for (int i = 0; i < 8; ++i) text += "v " + real() + " " + real() + " " + real() + "\n";
    // No "v/t/n" without a vt: Assimp then read a fourth field past the end of the line.
    full_corners_ = below(3) != 0;
    for (int i = 0; i < 4 && full_corners_; ++i) text += "vt " + real() + " " + real() + "\n";
    for (int i = 0; i < 4 && below(3) != 0; ++i) text += "vn " + real() + " " + real() + " 1\n";
    for (int lines = 4 + below(40); lines-- > 0;) text += line();
    return text;
  }

 private:
  int below(int n) { return int(random_() % std::uint32_t(n)); }
  std::string pick(std::initializer_list<const char*> options) {
    return *(options.begin() + below(int(options.size())));
  }
  std::string real() {
    return pick({"", "-", "+"}) + std::to_string(below(3)) +
           pick({"", ".", ".5", ".25", ",5", ".125e1", "e-1", ".0"});
  }
  std::string index(int count = 4) {
    const int i = 1 + below(count);
    return below(5) == 0 ? "-" + std::to_string(i) : std::to_string(i);
  }
  std::string corner() {
    switch (below(4)) {
      case 0:
        return index(8);
      case 1:
        return index(8) + "/" + index();
      case 2:
        return index(8) + "//" + index();
      default:
        return full_corners_ ? index(8) + "/" + index() + "/" + index() : index(8);
    }
  }
  std::string line() {
    std::string out;
    switch (below(12)) {
      case 0:
      case 1:
      case 2:
        out = "v";
        for (int k = below(16) == 0 ? 2 + below(6) : 3; k-- > 0;) out += " " + real();
        break;
      case 3:
        out = pick({"vt ", "vn "}) + real() + " " + real() + " " + real();
        break;
      case 4:
      case 5:
      case 6:
        out = pick({"f", "f", "l", "p"});
        for (int k = 1 + below(below(3) == 0 ? 8 : 4); k-- > 0;) out += " " + corner();
        if (out[0] == 'l' && below(8) != 0) out += " " + corner();  // a lone corner: refused
        break;
      case 7:
        out = pick({"g a", "g b", "g", "o x", "o y", "s 1", "s off"});
        break;
      case 8:
        out = pick({"usemtl red", "usemtl blue", "usemtl plain", "usemtl other", "usemtl grey"});
        break;
      case 9:
        out = pick({"# comment", "", "  f 1 2 3", "cstype rat", "end", "mg 1"});
        break;
      default:
        out = "f " + corner() + " " + corner() + pick({" \\\n", " "}) + corner();
        break;
    }
    return out + pick({"\n", "\n", "\r\n", "  \n"});
  }
  std::mt19937 random_;
  bool full_corners_ = true;
};

TEST(ObjImport, RandomFilesImportAsAssimpDid) {
  RandomObj random(19);
  for (int i = 0; i < 400; ++i) {
    const std::string name = "random file " + std::to_string(i);
    expect_as_assimp({name.c_str(), random.file(), {{"m.mtl", kMtl}}});
    if (HasFailure()) break;
  }
}

// ---------------------------------------------------------------------------------------------
// The rules, with what they give worked out by hand

// Imports `text` as mesh.obj in a fresh folder (with `companions` beside it), as import_file does.
ImportedFile import_text(const std::string& text,
                         const std::vector<std::pair<std::string, std::string>>& companions = {},
                         const ImportLimits& limits = {}) {
  test::TempDir dir;
  test::write_text(dir.file("mesh.obj"), text);
  for (const auto& [name, body] : companions) test::write_text(dir.file(name), body);
  return import_file(dir.file("mesh.obj"), limits);
}

// The one-line ImportError `text` gives as mesh.obj, without the path and its ": ".
std::string import_error(const std::string& text, const ImportLimits& limits = {}) {
  test::TempDir dir;
  const std::string path = dir.file("mesh.obj");
  test::write_text(path, text);
  try {
    import_file(path, limits);
  } catch (const ImportError& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind(path, 0), 0u) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    return message.substr(path.size());
  }
  return "no error";
}

#define EXPECT_REFUSED(text, needle)                                        \
  do {                                                                      \
    const std::string reason = import_error(text);                          \
    EXPECT_NE(reason.find(needle), std::string::npos) << "got: " << reason; \
  } while (0)

// Negative indices count back from the vertices read so far; every corner is a vertex until
// joined, so the second triangle reuses the first one's vertices 0 and 2.
TEST(ObjImport, NegativeIndicesAndJoinedCorners) {
  const ImportedFile file = import_text(kSquare + "f -4 -3 -2\nf 1 3 -1\n");
  ASSERT_EQ(file.meshes.size(), 1u);
  const ImportedMesh& mesh = file.meshes[0];
  EXPECT_EQ(mesh.name, "defaultobject");
  EXPECT_EQ(triangles_of(mesh), (std::vector<Tri>{{0, 1, 2}, {0, 2, 3}}));
  ASSERT_EQ(mesh.positions.size(), 4u);
  EXPECT_EQ(mesh.positions[3].y, 1.0f);
  EXPECT_TRUE(mesh.normals.empty());
  EXPECT_TRUE(mesh.colors.empty());
}

// v//vn and v/vt/vn: corners at one position stay apart when their normals or texture
// coordinates differ by more than 1e-5.
TEST(ObjImport, CornerFormsKeepDifferentNormalsApart) {
  const ImportedMesh normals =
      import_text(kSquare + "vn 0 0 1\nvn 0 0 -1\nf 1//1 2//1 3//1\nf 1//2 3//2 4//2\n")
          .meshes.at(0);
  EXPECT_EQ(triangles_of(normals), (std::vector<Tri>{{0, 1, 2}, {3, 4, 5}}));
  ASSERT_EQ(normals.normals.size(), 6u);
  EXPECT_EQ(normals.normals[3].z, -1.0f);
  const ImportedMesh uvs = import_text(kSquare +
                                       "vt 0 0\nvt 0 0.000001\nvt 1 1\nvn 0 0 1\n"
                                       "f 1/1/1 2/3/1 3/3/1\nf 1/2/1 3/1/1 4/1/1\n")
                               .meshes.at(0);
  // Corner 1/2 joins 1/1 (their coordinates within 1e-5); 3/1 does not join 3/3.
  EXPECT_EQ(triangles_of(uvs), (std::vector<Tri>{{0, 1, 2}, {0, 3, 4}}));
}

// A backslash before the line end joins the next line; \r\n works; a quad fans from a corner.
TEST(ObjImport, LineContinuation) {
  const ImportedMesh mesh = import_text(kSquare + "f 1 2 \\\r\n3 4\r\n").meshes.at(0);
  EXPECT_EQ(triangles_of(mesh), (std::vector<Tri>{{0, 1, 2}, {0, 2, 3}}));
}

// A mesh per group and per material change inside it (named after the material), base colours
// from the .mtl; a material equal to Assimp's default has none.
TEST(ObjImport, GroupsMaterialsAndBaseColours) {
  const ImportedFile file = import_text(
      "mtllib m.mtl\n" + kSquare +
          "g a\nusemtl red\nf 1 2 3\nusemtl blue\nf 1 3 4\ng b\nusemtl plain\nf 1 2 4\n",
      {{"m.mtl", kMtl}});
  ASSERT_EQ(file.meshes.size(), 3u);
  EXPECT_EQ(file.meshes[0].name, "a");
  EXPECT_EQ(file.meshes[1].name, "blue");
  EXPECT_EQ(file.meshes[2].name, "b");
  EXPECT_EQ(file.meshes[0].colors, std::vector<std::uint32_t>(3, 0xFF0000FFu));
  EXPECT_EQ(file.meshes[1].colors, std::vector<std::uint32_t>(3, 0xFFFF0000u));
  EXPECT_TRUE(file.meshes[2].colors.empty());
  ASSERT_EQ(file.accessed.read.size(), 2u);
  EXPECT_TRUE(file.accessed.read[0].ends_with("/m.mtl"));
  EXPECT_TRUE(file.accessed.missing.empty());
}

// A missing .mtl is looked for where named, then under the OBJ's own name; both are recorded so
// that one appearing later invalidates the build cache. The materials are then defaults.
TEST(ObjImport, MissingMaterialLibrary) {
  const ImportedFile file =
      import_text("mtllib absent.mtl\n" + kSquare + "g part\nusemtl red\nf 1 2 3\n");
  ASSERT_EQ(file.meshes.size(), 1u);
  EXPECT_EQ(file.meshes[0].name, "part");
  EXPECT_TRUE(file.meshes[0].colors.empty());
  auto missing = [&](const std::string& name) {
    return std::any_of(file.accessed.missing.begin(), file.accessed.missing.end(),
                       [&](const std::string& path) { return path.ends_with("/" + name); });
  };
  EXPECT_TRUE(missing("absent.mtl"));
  EXPECT_TRUE(missing("mesh.mtl"));
}

// Read from memory (a .zst, a UTF-16 file, the fuzzers) no companion is opened: Assimp looked in
// the working directory, then parsed the OBJ itself as the .mtl.
TEST(ObjImport, FromMemoryNoLibraryIsRead) {
  // (A `usemtl` before any face or group makes a mesh of no object, never output: the faces
  // go to "defaultobject", as in Assimp.)
  const std::string text = "mtllib m.mtl\n" + kSquare + "usemtl red\nf 1 2 3\n";
  const ImportedFile file = import_bytes("mesh.obj", bytes_of(text), {}, false);
  ASSERT_EQ(file.meshes.size(), 1u);
  EXPECT_EQ(file.meshes[0].name, "defaultobject");
  EXPECT_TRUE(file.meshes[0].colors.empty());
  EXPECT_EQ(file.accessed.read.size(), 1u);
  EXPECT_TRUE(file.accessed.missing.empty());
}

// Vertices alone are one point cloud named after the file (from memory Assimp named it
// "$$$___magic___$$$.obj"); lines alone carry no surface and are dropped.
TEST(ObjImport, PointCloudsAndWireframes) {
  const ImportedFile cloud = import_bytes("dir/scan.obj", bytes_of(kSquare), {}, false);
  ASSERT_EQ(cloud.meshes.size(), 1u);
  EXPECT_EQ(cloud.meshes[0].name, "scan.obj");
  EXPECT_TRUE(cloud.meshes[0].point_cloud);
  EXPECT_EQ(cloud.meshes[0].positions.size(), 4u);
  EXPECT_NE(import_error(kSquare + "l 1 2 3 4 1\n").find("no triangles"), std::string::npos);
}

// Refused in one line, naming the line where the fault is on one.
TEST(ObjImport, MalformedFilesAreRefused) {
  EXPECT_REFUSED(kSquare + "f 1 2 9\n", ": a face names a vertex beyond the 4 in the file");
  EXPECT_REFUSED(kSquare + "f 1 2 -9\n", ": a face names a vertex beyond the 4 in the file");
  EXPECT_REFUSED(kSquare + "f 1 x 3\n", ":5: face index 'x' is not a nonzero integer");
  EXPECT_REFUSED(kSquare + "f 0 1 2\n", ":5: face index '0' is not a nonzero integer");
  EXPECT_REFUSED("v 1 2 3\nv 1 zero 2 3\nf 1 2 3\n", ":2: 'zero' is not a number");
  EXPECT_REFUSED(kSquare + "vt 1\nf 1 2 3\n", ":5: a texture coordinate of 1 numbers");
  EXPECT_REFUSED("v 1 2 3 0\nv 0 0 0\nv 1 0 0\nf 1 2 3\n", ":1: a homogeneous vertex with w = 0");
  EXPECT_REFUSED("mtllib b.mtl\n" + kSquare, "");
  EXPECT_REFUSED("v 0 0 0\np 1\n", ": 12 bytes, too small for an OBJ file");
  EXPECT_REFUSED("", ": file is empty");
  EXPECT_REFUSED("# only a comment, no vertex\n", "contains no triangles");
}

// A .mtl that Assimp could not read fails the file, naming the .mtl.
TEST(ObjImport, MalformedMaterialLibraryIsRefused) {
  test::TempDir dir;
  test::write_text(dir.file("mesh.obj"), "mtllib b.mtl\n" + kSquare + "f 1 2 3\n");
  test::write_text(dir.file("b.mtl"), "newmtl b\nKd 1 one 1\n");
  try {
    import_file(dir.file("mesh.obj"));
    ADD_FAILURE() << "accepted";
  } catch (const ImportError& e) {
    EXPECT_EQ(std::string(e.what()),
              dir.file("mesh.obj") + ":1: 'one' is not a number in " + dir.file("b.mtl"));
  }
}

// The polygon limit, with the Assimp path's message, before anything is triangulated; also for
// a face keyword check_obj_faces does not count ("fo" reads as a face too).
TEST(ObjImport, PolygonLimit) {
  ImportLimits limits;
  limits.max_face_vertices = 5;
  const std::string hexagon = "v 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 2 0\nv -1 1 0\n";
  EXPECT_EQ(import_error(hexagon + "f 1 2 3 4 5 6\n", limits),
            ":7: a face with 6 corners; the limit is 5 (raise it with --max-face-vertices)");
  EXPECT_EQ(import_error(hexagon + "fo 1 2 3 4 5 6\n", limits),
            ":7: a face with more than 5 corners (raise it with --max-face-vertices)");
  EXPECT_EQ(import_text(hexagon + "f 1 2 3 4 5\nl 1 2 3 4 5 6\n", {}, limits)
                .meshes.at(0)
                .triangles.size(),
            3u);
}

// Hostile input: nothing in an OBJ declares a count, so what is stored grows with the bytes
// read (a corner costs at least two bytes of text); absurd indices are refused, not allocated.
TEST(ObjImport, HostileIndicesAreRefusedWithoutAllocating) {
  EXPECT_REFUSED(kSquare + "f 1 2 4294967295\n", "a face names a vertex beyond the 4");
  EXPECT_REFUSED(kSquare + "f 1 2 99999999999999999999999\n", "a face names a vertex beyond");
  EXPECT_REFUSED(kSquare + "f 1 2 -2147483648\n", "a face names a vertex beyond");
  std::string points = kSquare + "p";
  for (int i = 0; i < 200000; ++i) points += " 1";
  const ImportedFile file = import_text(points + "\n");
  ASSERT_EQ(file.meshes.size(), 1u);
  EXPECT_EQ(file.meshes[0].positions.size(), 1u);  // 200,000 corners joined into one vertex
  EXPECT_TRUE(file.meshes[0].point_cloud);
}

// Where Assimp's behaviour was a bug, Kiln differs, on purpose:
// - a fourth '/' field in a corner: Assimp skipped to the end of the line and then went on
//   parsing stale bytes of earlier lines from its buffer; Kiln ends the face there;
// - an MTL statement before any `newmtl` (or `usemtl`): Assimp dereferenced a null material and
//   crashed; Kiln ignores the statement.
TEST(ObjImport, AssimpBugsAreNotReproduced) {
  const ImportedMesh ended =
      import_text(kSquare + "vt 0 0\nvn 0 0 1\nf 1 2 3/1/1/1 4\n").meshes.at(0);
  EXPECT_EQ(triangles_of(ended), (std::vector<Tri>{{0, 1, 2}}));
  const ImportedFile file = import_text("mtllib c.mtl\n" + kSquare + "usemtl x\nf 1 2 3\n",
                                        {{"c.mtl", "map_Kd a.png\naniso 1\nnewmtl x\nKd 1 1 0\n"}});
  EXPECT_EQ(file.meshes.at(0).colors, std::vector<std::uint32_t>(3, 0xFF00FFFFu));
}

}  // namespace
}  // namespace kiln
