// Kiln's STL reader (compiler/src/import_stl.cpp): binary and ASCII files written here byte by
// byte, compared with what the Assimp path (import_with_assimp) gives for them wherever Assimp
// reads them; hostile files refused early with one line; every shared STL as Assimp imported it.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "import_fixtures.hpp"
#include "kiln/compiler/build.hpp"
#include "kiln/compiler/import.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

using Tri = std::array<std::uint32_t, 3>;
using Vec = std::array<float, 3>;

// A binary STL under construction: an 80-byte header, a count, then facets.
class BinaryStl {
 public:
  explicit BinaryStl(const std::string& header = "binary") {
    bytes_.resize(80);
    std::memcpy(bytes_.data(), header.data(), std::min<std::size_t>(header.size(), 80));
    put(std::uint32_t(0));
  }
  BinaryStl& facet(Vec normal, Vec a, Vec b, Vec c, std::uint16_t attribute = 0) {
    for (const Vec& v : {normal, a, b, c})
      for (const float x : v) put(x);
    put(attribute);
    const std::uint32_t count = std::uint32_t((bytes_.size() - 84) / 50);
    std::memcpy(bytes_.data() + 80, &count, 4);
    return *this;
  }
  BinaryStl& count(std::uint32_t count) {
    std::memcpy(bytes_.data() + 80, &count, 4);
    return *this;
  }
  std::vector<std::byte> bytes() const { return bytes_; }

 private:
  template <class T>
  void put(T value) {  // little-endian host (x86-64, aarch64)
    const auto* raw = reinterpret_cast<const std::byte*>(&value);
    bytes_.insert(bytes_.end(), raw, raw + sizeof(T));
  }
  std::vector<std::byte> bytes_;
};

std::vector<std::byte> text(const std::string& s) {
  const auto* raw = reinterpret_cast<const std::byte*>(s.data());
  return {raw, raw + s.size()};
}

// An ASCII facet with the usual keywords.
std::string facet(const std::string& normal, const std::string& a, const std::string& b,
                  const std::string& c) {
  return "  facet normal " + normal + "\n    outer loop\n      vertex " + a + "\n      vertex " +
         b + "\n      vertex " + c + "\n    endloop\n  endfacet\n";
}

std::vector<Tri> triangles_of(const ImportedMesh& mesh) {
  std::vector<Tri> out;
  for (const auto& t : mesh.triangles) out.push_back({t.v[0], t.v[1], t.v[2]});
  return out;
}

void expect_same_scene(const Scene& mine, const Scene& assimp) {
  auto same = [](const auto& a, const auto& b) {
    return a.size() == b.size() &&
           (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(a[0])) == 0);
  };
  EXPECT_TRUE(same(mine.positions, assimp.positions));
  EXPECT_TRUE(same(mine.normals, assimp.normals));
  EXPECT_TRUE(same(mine.colors, assimp.colors));
  EXPECT_TRUE(same(mine.triangles, assimp.triangles));
  EXPECT_TRUE(same(mine.triangle_mesh, assimp.triangle_mesh));
  EXPECT_EQ(mine.input_triangle_count, assimp.input_triangle_count);
  ASSERT_EQ(mine.meshes.size(), assimp.meshes.size());
  for (std::size_t m = 0; m < mine.meshes.size(); ++m) {
    EXPECT_EQ(mine.meshes[m].name, assimp.meshes[m].name);
    EXPECT_EQ(mine.meshes[m].vertex_count, assimp.meshes[m].vertex_count);
  }
}

// The file at `path` through Kiln's reader and through Assimp, each assembled into a scene.
void expect_as_assimp(const std::string& path) {
  const Scene scene = import_scene({path}, 1);
  ImportedFile assimp;
  assimp.source = scene.sources.at(0);
  assimp.meshes = import_with_assimp(path, test::read_file(path), ".stl", true, {});
  std::vector<ImportedFile> files;
  files.push_back(std::move(assimp));
  expect_same_scene(scene, assemble_scene(std::move(files)));
}

// Imports `bytes` as mesh.stl with Kiln's reader; also checks that Assimp reads them alike.
std::vector<ImportedMesh> import_stl_bytes(const std::vector<std::byte>& bytes) {
  test::TempDir dir;
  const std::string path = dir.file("mesh.stl");
  test::write_file(path, bytes);
  expect_as_assimp(path);
  return import_file(path).meshes;
}

// The one-line ImportError `bytes` give as mesh.stl (never shown to Assimp: it leaks on some).
std::string import_error(const std::vector<std::byte>& bytes) {
  return test::import_refusal("mesh.stl", bytes);
}

// ---------------------------------------------------------------------------------------------
// Binary

// Two facets sharing an edge with the same normal: the shared corners are joined, the normal
// given to every vertex; a header starting with "solid" is still binary when the size fits.
TEST(StlImport, BinaryFacetsJoinSharedCorners) {
  for (const char* header : {"binary from a test", "solid cube (binary, as exporters write)"}) {
    SCOPED_TRACE(header);
    const auto meshes = import_stl_bytes(BinaryStl(header)
                                             .facet({0, 0, 1}, {0, 0, 0}, {1, 0, 0}, {1, 1, 0})
                                             .facet({0, 0, 1}, {0, 0, 0}, {1, 1, 0}, {0, 1, 0})
                                             .bytes());
    ASSERT_EQ(meshes.size(), 1u);
    EXPECT_EQ(meshes[0].name, "");
    EXPECT_EQ(triangles_of(meshes[0]), (std::vector<Tri>{{0, 1, 2}, {0, 2, 5}}));
    ASSERT_EQ(meshes[0].normals.size(), 6u);
    EXPECT_EQ(meshes[0].normals[4].z, 1.0f);
    EXPECT_EQ(meshes[0].positions[5].y, 1.0f);
    EXPECT_TRUE(meshes[0].colors.empty());
  }
}

// Different normals keep corners apart (flat shading), as Assimp's join did.
TEST(StlImport, BinaryCornersWithOtherNormalsStayApart) {
  const auto meshes = import_stl_bytes(BinaryStl()
                                           .facet({0, 0, 1}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0})
                                           .facet({0, -1, 0}, {0, 0, 0}, {0, 0, 1}, {1, 0, 0})
                                           .bytes());
  ASSERT_EQ(meshes.size(), 1u);
  EXPECT_EQ(triangles_of(meshes[0]), (std::vector<Tri>{{0, 1, 2}, {3, 4, 5}}));
}

// VisCAM/SolidView colours: bit 15 set, blue in the low 5 bits; once a facet is coloured, the
// others take Assimp's default grey with alpha 0.6 (153).
TEST(StlImport, BinaryFacetColors) {
  const auto meshes =
      import_stl_bytes(BinaryStl()
                           .facet({0, 0, 1}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0})
                           .facet({0, 0, 1}, {5, 0, 0}, {6, 0, 0}, {5, 1, 0}, 0x8000 | 31 << 10)
                           .facet({0, 0, 1}, {9, 0, 0}, {8, 0, 0}, {9, 1, 0}, 0x8000 | 31 | 16 << 5)
                           .bytes());
  ASSERT_EQ(meshes.size(), 1u);
  ASSERT_EQ(meshes[0].colors.size(), 9u);
  EXPECT_EQ(meshes[0].colors[0], test::rgba(153, 153, 153, 153));
  EXPECT_EQ(meshes[0].colors[3], test::rgba(255, 0, 0, 255));
  EXPECT_EQ(meshes[0].colors[8], test::rgba(0, 132, 255, 255));
  // No coloured facet: no colours, whatever the other attribute bits say.
  const auto plain = import_stl_bytes(
      BinaryStl().facet({0, 0, 1}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 0x7FFF).bytes());
  EXPECT_TRUE(plain.at(0).colors.empty());
}

// Materialise: "COLOR=" and four bytes in the header give the default colour, and a facet's red
// is in its low bits (Assimp's reading, bit 15 included, kept).
TEST(StlImport, BinaryMaterialiseColors) {
  std::string header = "made by Magics COLOR=";
  header += std::string("\x0a\x14\x1e\xff", 4);
  const auto meshes =
      import_stl_bytes(BinaryStl(header)
                           .facet({0, 0, 1}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0})
                           .facet({0, 0, 1}, {5, 0, 0}, {6, 0, 0}, {5, 1, 0}, 0x8000 | 31)
                           .bytes());
  ASSERT_EQ(meshes.at(0).colors.size(), 6u);
  EXPECT_EQ(meshes[0].colors[0], test::rgba(10, 20, 30, 255));
  EXPECT_EQ(meshes[0].colors[3], test::rgba(255, 0, 0, 255));
  // Assimp's header scan consumes the byte that fails to match: "CCOLOR=" is not found.
  const auto missed =
      import_stl_bytes(BinaryStl("CCOLOR=\x01\x02\x03\x04")
                           .facet({0, 0, 1}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 0x8000 | 31)
                           .facet({0, 0, 1}, {5, 0, 0}, {6, 0, 0}, {5, 1, 0})
                           .bytes());
  ASSERT_EQ(missed.at(0).colors.size(), 6u);
  EXPECT_EQ(missed[0].colors[0], test::rgba(0, 0, 255, 255));
  EXPECT_EQ(missed[0].colors[3], test::rgba(153, 153, 153, 153));
}

TEST(StlImport, BadBinaryCountsAreRefused) {
  const auto two = BinaryStl()
                       .facet({0, 0, 1}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0})
                       .facet({0, 0, 1}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0})
                       .bytes();
  EXPECT_REFUSED(std::vector<std::byte>(two.begin(), two.end() - 1),
                 "not an STL file (no 'solid' at the start, and the binary count of 2 triangles "
                 "needs 184 bytes, not 183)");
  EXPECT_REFUSED(
      BinaryStl().facet({0, 0, 1}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}).count(4000000000u).bytes(),
      "the binary count of 4000000000 triangles needs 200000000084 bytes, not 134");
  EXPECT_REFUSED(BinaryStl().bytes(), "binary STL with no triangles");
  EXPECT_REFUSED(text("12 bytes, no"), "12 bytes are too few for binary");
  // 84 + 50 * 85899347 wraps around 2^32 to 138 in Assimp's 32-bit test: binary, then refused.
  auto wrapped = BinaryStl().facet({0, 0, 1}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}).bytes();
  wrapped.resize(138);
  const std::uint32_t count = 85899347;
  std::memcpy(wrapped.data() + 80, &count, 4);
  EXPECT_REFUSED(wrapped,
                 "binary STL claims 85899347 triangles (4294967434 bytes), more than the file's "
                 "138 bytes hold");
  // A truncated binary file whose header starts with "solid" is read as ASCII, as Assimp did.
  auto solid = BinaryStl("solid part").facet({0, 0, 1}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}).bytes();
  solid.pop_back();
  EXPECT_REFUSED(solid,
                 "ASCII STL with no facets (read as binary, its count of 1 triangles needs 134 "
                 "bytes, not 133)");
}

// ---------------------------------------------------------------------------------------------
// ASCII

// A mesh per solid with facets, named as the solid; an empty solid is left out, an unnamed one
// is named "" (Assimp named the root node instead).
TEST(StlImport, AsciiSolids) {
  const auto meshes = import_stl_bytes(
      text("solid first\n" + facet("0 0 1", "0 0 0", "1 0 0", "1 1 0") +
           facet("0 0 1", "0 0 0", "1 1 0", "0 1 0") + "endsolid first\nsolid empty\nendsolid\n" +
           "solid\n" + facet("1 0 0", "2 0 0", "2 1 0", "2 0 1") + "endsolid\n"));
  ASSERT_EQ(meshes.size(), 2u);
  EXPECT_EQ(meshes[0].name, "first");
  EXPECT_EQ(triangles_of(meshes[0]), (std::vector<Tri>{{0, 1, 2}, {0, 2, 5}}));
  EXPECT_EQ(meshes[1].name, "");
  EXPECT_EQ(triangles_of(meshes[1]), (std::vector<Tri>{{0, 1, 2}}));
  EXPECT_EQ(meshes[1].positions[2].z, 1.0f);
  EXPECT_EQ(meshes[1].normals[0].x, 1.0f);
}

// What Assimp tolerated, read as it read it: CRLF and tabs, numbers in every form Assimp took,
// a vertex before any facet or past a facet's third (ignored), unknown words, no endsolid at
// the end, text after the last endsolid that is no solid.
TEST(StlImport, AsciiAsAssimpReadIt) {
  const auto meshes = import_stl_bytes(
      text("  solid\tpart extra words\r\n vertex 9 9 9\r\n"
           "facet normal 0 0 1\r\n outer loop\r\n\tvertex 1.5e+000 -.25 +3.\r\n"
           "vertex 1E2 0.000000000000000000001 -0\r\n vertex 1.0 2.0 3.0\r\n"
           "vertex 7 7 7\r\n endloop\r\n endfacet\r\nendsolid part\r\n"
           "solid second\n" +
           facet("0 0 -1", "0 0 0", "1 0 0", "0 1 0") + "\nendsolidXY\ngarbage after\n"));
  ASSERT_EQ(meshes.size(), 2u);
  EXPECT_EQ(meshes[0].name, "part");
  ASSERT_EQ(meshes[0].positions.size(), 3u);
  EXPECT_EQ(meshes[0].positions[0].x, 1.5f);
  EXPECT_EQ(meshes[0].positions[0].y, -0.25f);
  EXPECT_EQ(meshes[0].positions[1].x, 100.0f);
  EXPECT_EQ(meshes[1].name, "second");
  const auto unterminated = import_stl_bytes(
      text("solid open\n" + facet("0 0 1", "0 0 0", "1 0 0", "0 1 0") + "endsolid"));
  EXPECT_EQ(unterminated.size(), 1u);
  const auto no_end =
      import_stl_bytes(text("solid open\n" + facet("0 0 1", "0 0 0", "1 0 0", "0 1 0")));
  EXPECT_EQ(no_end.size(), 1u);
}

TEST(StlImport, BadAsciiIsRefused) {
  const std::string head = "solid bad\n  facet normal 0 0 1\n    outer loop\n";
  EXPECT_REFUSED(text(head + "      vertex 0 zero 0\n"),
                 "line 4: a vertex: 'zero' is not a number");
  EXPECT_REFUSED(text(head + "      vertex 0 1.5abc 0\n"), "'1.5abc' is not a number");
  EXPECT_REFUSED(text(head + "      vertex 0 1,5 0\n"), "'1,5' is not a number");
  EXPECT_REFUSED(text(head + "      vertex 0 1\n 2\n"),
                 "line 4: a vertex has fewer than 3 numbers");
  EXPECT_REFUSED(text("solid x\nfacet normal 0 0 one\n"), "line 2: a facet normal: 'one' is not");
  EXPECT_REFUSED(text(head + "vertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid\n"),
                 "solid 'bad' has 2 vertices and 1 facet normals; a facet needs a normal and 3");
  EXPECT_REFUSED(text("solid x\nfacet\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendsolid\n"),
                 "solid 'x' has 3 vertices and 0 facet normals");
  EXPECT_REFUSED(text(head + "vertex"), "line 4: the file ends inside a facet");
  EXPECT_REFUSED(text("solid nothing here\nendsolid\n"), "ASCII STL with no facets");
  EXPECT_REFUSED(text("solid"), "not an STL file (no 'solid' at the start");
  EXPECT_REFUSED(text("\nsolid x\n" + facet("0 0 1", "0 0 0", "1 0 0", "0 1 0")),
                 "not an STL file");  // Assimp looked past spaces and tabs only
  EXPECT_REFUSED(text("solid " + std::string(1024, 'n') + "\n"), "a solid name of 1024");
  // The fuzzer's input that made Assimp 5.2.5 leak: a facet normal that is not a number.
  const std::string leak = test::read_text(KILN_FUZZ_DIR "/regressions/stl/assimp-ascii-leak");
  EXPECT_REFUSED(text(leak), "line 2: a facet normal: '");
}

// A NaN or infinite coordinate passes the reader; assemble_scene drops its triangle, as for
// every format.
TEST(StlImport, NonFiniteCoordinatesDropTheirTriangles) {
  test::TempDir dir;
  const std::string ascii = dir.file("nan.stl");
  test::write_file(ascii, text("solid s\n" + facet("0 0 1", "0 0 0", "1 0 0", "0 1 0") +
                               facet("0 0 1", "nan 0 0", "1 0 0", "0 1 0") + "endsolid\n"));
  EXPECT_EQ(import_file(ascii).meshes.at(0).triangles.size(), 2u);
  EXPECT_EQ(import_scene({ascii}, 1).triangles.size(), 1u);
  const std::string binary = dir.file("inf.stl");
  test::write_file(binary, BinaryStl()
                               .facet({0, 0, 1}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0})
                               .facet({0, 0, 1}, {0, INFINITY, 0}, {1, 0, 0}, {0, 1, 0})
                               .bytes());
  EXPECT_EQ(import_scene({binary}, 1).triangles.size(), 1u);
}

// UTF-16 text was transcoded before Assimp read it; it still is.
TEST(StlImport, Utf16AsciiIsTranscodedBinaryNever) {
  const std::string ascii =
      "solid wide\n" + facet("0 0 1", "0 0 0", "1 0 0", "0 1 0") + "endsolid\n";
  std::vector<std::byte> utf16{std::byte(0xFF), std::byte(0xFE)};
  for (const char c : ascii) utf16.insert(utf16.end(), {std::byte(c), std::byte(0)});
  test::TempDir dir;
  test::write_file(dir.file("wide.stl"), utf16);
  const auto meshes = import_file(dir.file("wide.stl")).meshes;
  ASSERT_EQ(meshes.size(), 1u);
  EXPECT_EQ(meshes[0].name, "wide");
  // A binary header may start like a UTF-16 BOM: the size decides first, and it stays binary
  // (Kiln used to transcode it, and Assimp then refused the mangled bytes).
  const auto binary = import_stl_bytes(
      BinaryStl("\xff\xfe header").facet({0, 0, 1}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}).bytes());
  EXPECT_EQ(binary.at(0).triangles.size(), 1u);
}

// ---------------------------------------------------------------------------------------------
// The shared corpus

struct SharedStl {
  const char* path;
  std::uint64_t triangles;  // MANIFEST.md (facets in the file)
  std::size_t meshes;
};

constexpr SharedStl kSharedStls[] = {
    {"assimp/STL/3DSMaxExport.STL", 2000, 1},
    {"assimp/STL/Spider_ascii.stl", 1368, 1},
    {"assimp/STL/Spider_binary.stl", 1368, 1},
    {"assimp/STL/Wuson.stl", 3732, 1},
    {"assimp/STL/sphereWithHole.stl", 285, 1},
    {"assimp/STL/triangle.stl", 1, 1},
    {"assimp/STL/triangle_with_empty_solid.stl", 1, 1},
    {"assimp/STL/triangle_with_two_solids.stl", 2, 2},
};

// Every shared STL bit for bit as the Assimp path imports it: positions, normals, colours,
// triangles, mesh names and vertex counts after assembly.
TEST(StlImport, SharedStlsImportAsBefore) {
  KILN_REQUIRE_CORPUS();
  for (const SharedStl& expected : kSharedStls) {
    SCOPED_TRACE(expected.path);
    const std::string path = test::mesh_path(expected.path);
    const ImportedFile file = import_file(path);
    EXPECT_EQ(file.meshes.size(), expected.meshes);
    std::uint64_t triangles = 0;
    for (const auto& mesh : file.meshes) triangles += mesh.triangles.size();
    EXPECT_EQ(triangles, expected.triangles);
    expect_as_assimp(path);
  }
}

}  // namespace
}  // namespace kiln
