// Kiln's PLY reader (compiler/src/import_ply.cpp): files written here byte by byte, ASCII and
// binary of both endiannesses, faces and triangle strips, with the triangles expected worked out
// by hand; hostile headers refused early with one line; every shared PLY as the Assimp path
// imported it before.
#include <algorithm>
#include <array>
#include <bit>
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

// A PLY file under construction: header text, then values in the file's byte order.
class PlyBytes {
 public:
  explicit PlyBytes(bool big_endian = false) : big_endian_(big_endian) {}
  PlyBytes& text(const std::string& s) {
    for (const char c : s) bytes_.push_back(std::byte(c));
    return *this;
  }
  template <class T>
  PlyBytes& put(T value) {
    std::array<std::byte, sizeof(T)> raw;
    std::memcpy(raw.data(), &value, sizeof(T));
    if (big_endian_ != (std::endian::native == std::endian::big))
      std::reverse(raw.begin(), raw.end());
    bytes_.insert(bytes_.end(), raw.begin(), raw.end());
    return *this;
  }
  // A list's length as `count_type` (uchar, ushort or uint), then its items as T.
  template <class T>
  PlyBytes& list(const std::string& count_type, const std::vector<T>& items) {
    if (count_type == "uchar") put(std::uint8_t(items.size()));
    if (count_type == "ushort") put(std::uint16_t(items.size()));
    if (count_type == "uint") put(std::uint32_t(items.size()));
    for (const T item : items) put(item);
    return *this;
  }
  std::vector<std::byte> bytes() const { return bytes_; }

 private:
  bool big_endian_;
  std::vector<std::byte> bytes_;
};

std::string binary_format(bool big_endian) {
  return big_endian ? "format binary_big_endian 1.0\n" : "format binary_little_endian 1.0\n";
}

std::vector<std::byte> ascii(const std::string& text) {
  return PlyBytes().text(text).bytes();
}

// Imports `bytes` as a .ply file: its one mesh, as the importer gave it (before assembly).
ImportedMesh import_ply_bytes(const std::vector<std::byte>& bytes) {
  test::TempDir dir;
  const std::string path = dir.file("mesh.ply");
  test::write_file(path, bytes);
  ImportedFile file = import_file(path);
  if (file.meshes.size() != 1) ADD_FAILURE() << file.meshes.size() << " meshes";
  return file.meshes.empty() ? ImportedMesh{} : std::move(file.meshes[0]);
}

std::vector<Tri> triangles_of(const ImportedMesh& mesh) {
  std::vector<Tri> out;
  for (const auto& t : mesh.triangles) out.push_back({t.v[0], t.v[1], t.v[2]});
  return out;
}

// The one-line ImportError `bytes` give as mesh.ply; it must name the file.
std::string import_error(const std::vector<std::byte>& bytes) {
  return test::import_refusal("mesh.ply", bytes);
}

// ---------------------------------------------------------------------------------------------

// A quad fans into (0 1 2) (0 2 3); unknown properties, lists and elements are read past.
TEST(PlyImport, AsciiQuadAndTriangle) {
  const ImportedMesh mesh = import_ply_bytes(ascii(
      "ply\r\nformat ascii 1.0\ncomment made by hand\nobj_info scanner 1\n"
      "element vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
      "property float confidence\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
      "element face 2\nproperty uchar flags\nproperty list uchar int vertex_indices\n"
      "property list uchar float texcoord\n"
      "element material 1\nproperty uchar diffuse_red\nend_header\n"
      "0 0 0 0.5 255 0 0\n1 0 0 0.5 0 255 0\n1 1 0 0.5 0 0 255\n"
      "0 1 0 0.5 10 20 30\n2 0.5 -5e-1 1 1 1 1\n"
      "0 4 0 1 2 3 2 0.5 0.5\n\n1 3 1 4 2 0\n7\n"));
  EXPECT_EQ(triangles_of(mesh), (std::vector<Tri>{{0, 1, 2}, {0, 2, 3}, {1, 4, 2}}));
  ASSERT_EQ(mesh.positions.size(), 5u);
  EXPECT_EQ(mesh.positions[4].x, 2.0f);
  EXPECT_EQ(mesh.positions[4].y, 0.5f);
  EXPECT_EQ(mesh.positions[4].z, -0.5f);
  EXPECT_TRUE(mesh.normals.empty());
  EXPECT_EQ(mesh.colors,
            (std::vector<std::uint32_t>{test::rgba(255, 0, 0, 255), test::rgba(0, 255, 0, 255),
                                        test::rgba(0, 0, 255, 255), test::rgba(10, 20, 30, 255),
                                        test::rgba(1, 1, 1, 255)}));
  EXPECT_FALSE(mesh.point_cloud);
}

// Normals only when nx, ny and nz are all there; float colours as they are, alpha too.
TEST(PlyImport, NormalsAndFloatColors) {
  const std::string head =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
      "property float y\nproperty float z\nproperty float nx\n";
  const std::string faces = "element face 1\nproperty list uchar uint vertex_index\nend_header\n";
  const ImportedMesh all = import_ply_bytes(
      ascii(head +
            "property float ny\nproperty float nz\nproperty float red\nproperty float "
            "green\nproperty float blue\nproperty float alpha\n" +
            faces + "0 0 0 0 0 1 1 0 0 1\n1 0 0 0 0 1 0 1 0 0.5\n0 1 0 0 0 1 0 0 1 0\n3 0 1 2\n"));
  ASSERT_EQ(all.normals.size(), 3u);
  EXPECT_EQ(all.normals[1].z, 1.0f);
  EXPECT_EQ(all.colors,
            (std::vector<std::uint32_t>{test::rgba(255, 0, 0, 255), test::rgba(0, 255, 0, 128),
                                        test::rgba(0, 0, 255, 0)}));
  const ImportedMesh partial =
      import_ply_bytes(ascii(head + faces + "0 0 0 1\n1 0 0 1\n0 1 0 1\n3 0 1 2\n"));
  EXPECT_TRUE(partial.normals.empty());
  EXPECT_TRUE(partial.colors.empty());
  EXPECT_EQ(triangles_of(partial), (std::vector<Tri>{{0, 1, 2}}));
}

// As Assimp's JoinIdenticalVertices did: a used vertex identical to an earlier one (position,
// normal) becomes it; one of another colour stays apart.
TEST(PlyImport, IdenticalVerticesJoin) {
  const ImportedMesh mesh = import_ply_bytes(ascii(
      "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
      "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
      "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0 1 2 3\n1 0 0 1 2 3\n0 1 0 1 2 3\n-0 0 0 1 2 3\n1 0 0 9 9 9\n3 3 1 2\n3 0 4 2\n"));
  EXPECT_EQ(triangles_of(mesh), (std::vector<Tri>{{0, 1, 2}, {0, 4, 2}}));
}

TEST(PlyImport, VerticesAloneAreAPointCloud) {
  const ImportedMesh mesh = import_ply_bytes(
      ascii("ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\nproperty double y\n"
            "property double z\nelement face 0\nproperty list uchar int vertex_indices\n"
            "end_header\n0 0 0\n1 2 3\n"));
  EXPECT_TRUE(mesh.point_cloud);
  EXPECT_TRUE(mesh.triangles.empty());
  ASSERT_EQ(mesh.positions.size(), 2u);
  EXPECT_EQ(mesh.positions[1].z, 3.0f);
}

// Polygons in binary with every list type Kiln meets: uchar, ushort and uint counts; uchar,
// ushort, int and uint indices.
TEST(PlyImport, BinaryFacesWithAnyIntegerLists) {
  for (const bool big : {false, true}) {
    for (const std::string lists : {"uchar uchar", "ushort ushort", "uint int", "uchar uint"}) {
      SCOPED_TRACE(std::string(big ? "big endian, " : "little endian, ") + lists);
      const std::string count_type = lists.substr(0, lists.find(' '));
      const std::string item_type = lists.substr(lists.find(' ') + 1);
      PlyBytes ply(big);
      ply.text("ply\n" + binary_format(big) +
               "element vertex 5\nproperty short x\nproperty uchar y\nproperty double z\n"
               "element face 2\nproperty list " +
               count_type + " " + item_type + " vertex_indices\nproperty int flags\nend_header\n");
      const std::int16_t xs[] = {0, 1, 1, 0, -2};
      const std::uint8_t ys[] = {0, 0, 1, 1, 3};
      for (int v = 0; v < 5; ++v) ply.put(xs[v]).put(ys[v]).put(0.25 * v);
      auto face = [&](const std::vector<std::uint32_t>& indices) {
        if (item_type == "uchar")
          ply.list(count_type, std::vector<std::uint8_t>(indices.begin(), indices.end()));
        if (item_type == "ushort")
          ply.list(count_type, std::vector<std::uint16_t>(indices.begin(), indices.end()));
        if (item_type == "int")
          ply.list(count_type, std::vector<std::int32_t>(indices.begin(), indices.end()));
        if (item_type == "uint") ply.list(count_type, indices);
        ply.put(std::int32_t(-7));
      };
      face({4, 3, 2, 1, 0});
      face({2, 0, 1});
      const ImportedMesh mesh = import_ply_bytes(ply.bytes());
      EXPECT_EQ(triangles_of(mesh), (std::vector<Tri>{{4, 3, 2}, {4, 2, 1}, {4, 1, 0}, {2, 0, 1}}));
      ASSERT_EQ(mesh.positions.size(), 5u);
      EXPECT_EQ(mesh.positions[4].x, -2.0f);
      EXPECT_EQ(mesh.positions[4].y, 3.0f);
      EXPECT_EQ(mesh.positions[4].z, 1.0f);
    }
  }
}

// Eight vertices on a zigzag, two tristrips entries. Entry 0: 0 1 2 3 4 | 5 6 7 | 2 2 3 4 (a
// joint: its first triangle names 2 twice and is left out, but still counts for the parity).
// Entry 1 starts afresh. Triangle i of a run is (a b c) for even i, (b a c) for odd i.
std::vector<std::byte> strip_file(bool big, const std::string& count_type) {
  PlyBytes ply(big);
  ply.text("ply\n" + binary_format(big) +
           "comment strips\nelement vertex 8\nproperty float x\nproperty double quality\n"
           "property float y\nproperty float z\nproperty uchar flags\n"
           "element tristrips 2\nproperty list " +
           count_type + " int vertex_indices\nproperty float extra\nend_header\n");
  for (int v = 0; v < 8; ++v)
    ply.put(float(v)).put(0.5).put(float(v % 2)).put(0.0f).put(std::uint8_t(7));
  ply.list(count_type, std::vector<std::int32_t>{0, 1, 2, 3, 4, -1, 5, 6, 7, -1, 2, 2, 3, 4});
  ply.put(1.5f);
  ply.list(count_type, std::vector<std::int32_t>{0, 1, 2, 3});
  ply.put(1.5f);
  return ply.bytes();
}

TEST(PlyImport, BinaryStripsWithRestartsBothEndiannesses) {
  const std::vector<Tri> expected = {{0, 1, 2}, {2, 1, 3}, {2, 3, 4}, {5, 6, 7},
                                     {3, 2, 4}, {0, 1, 2}, {2, 1, 3}};
  for (const bool big : {false, true}) {
    for (const std::string count_type : {"uchar", "ushort", "uint"}) {
      SCOPED_TRACE(std::string(big ? "big endian, " : "little endian, ") + count_type);
      const ImportedMesh mesh = import_ply_bytes(strip_file(big, count_type));
      EXPECT_EQ(triangles_of(mesh), expected);
      ASSERT_EQ(mesh.positions.size(), 8u);
      EXPECT_EQ(mesh.positions[7].x, 7.0f);
      EXPECT_EQ(mesh.positions[7].y, 1.0f);
      EXPECT_FALSE(mesh.point_cloud);
    }
  }
}

// An Igea-style scan (Cyberware): big-endian binary, one tristrips entry holding every strip, one
// per row of a grid, each closed by -1. A row of W columns gives 2W - 2 triangles, all facing
// the same way when the winding alternates right.
TEST(PlyImport, IgeaStyleStripFileImportsEveryTriangle) {
  constexpr std::int32_t kW = 20, kH = 15;
  PlyBytes ply(true);
  const std::int32_t strip_length = (kH - 1) * (2 * kW + 1);
  ply.text(
      "ply\nformat binary_big_endian 1.0\nobj_info is_cyberware_data 1\n"
      "element vertex " +
      std::to_string(kW * kH) +
      "\nproperty float x\nproperty float y\nproperty float z\nproperty float confidence\n"
      "element tristrips 1\nproperty list int int vertex_indices\nend_header\n");
  for (std::int32_t r = 0; r < kH; ++r)
    for (std::int32_t c = 0; c < kW; ++c) ply.put(float(c)).put(float(r)).put(0.0f).put(1.0f);
  ply.put(strip_length);
  for (std::int32_t r = 0; r + 1 < kH; ++r) {
    for (std::int32_t c = 0; c < kW; ++c) ply.put(r * kW + c).put((r + 1) * kW + c);
    ply.put(std::int32_t(-1));
  }
  test::TempDir dir;
  const std::string path = dir.file("igea_style.ply");
  test::write_file(path, ply.bytes());
  const Scene scene = import_scene({path}, 1);
  const std::uint64_t expected = std::uint64_t(kH - 1) * (2 * kW - 2);
  EXPECT_EQ(scene.input_triangle_count, expected);
  EXPECT_EQ(scene.triangles.size(), expected);
  EXPECT_EQ(scene.degenerate_triangles_dropped, 0u);
  EXPECT_EQ(scene.positions.size(), std::size_t(kW * kH));
  for (const auto& t : scene.triangles) {
    const auto &a = scene.positions[t.v[0]], &b = scene.positions[t.v[1]],
               &c = scene.positions[t.v[2]];
    const float z = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    EXPECT_LT(z, 0.0f) << t.v[0] << " " << t.v[1] << " " << t.v[2];
  }
}

// ---------------------------------------------------------------------------------------------
// Hostile and broken files: one line naming the file, refused before any large allocation.

const std::string kVertexXyz = "property float x\nproperty float y\nproperty float z\n";

TEST(PlyImport, CountsBeyondTheFileAreRefusedEarly) {
  PlyBytes binary;
  binary.text("ply\n" + binary_format(false) + "element vertex 1000000000000\n" + kVertexXyz +
              "end_header\n");
  for (int i = 0; i < 9; ++i) binary.put(1.0f);
  EXPECT_REFUSED(binary.bytes(), "vertex element: claims 1000000000000 entries");
  EXPECT_REFUSED(ascii("ply\nformat ascii 1.0\nelement vertex 1000000000000\n" + kVertexXyz +
                       "end_header\n0 0 0\n"),
                 "claims 1000000000000 entries");
  EXPECT_REFUSED(ascii("ply\nformat ascii 1.0\nelement vertex 99999999999999999999999\n" +
                       kVertexXyz + "end_header\n0 0 0\n"),
                 "header line 3");
  EXPECT_REFUSED(ascii("ply\nformat ascii 1.0\nelement junk 1000000000\nend_header\n"),
                 "junk element: has entries but no properties");

  PlyBytes list(true);  // a face whose list claims 10^8 indices
  list.text("ply\n" + binary_format(true) + "element vertex 3\n" + kVertexXyz +
            "element face 1\nproperty list uint int vertex_indices\nend_header\n");
  for (int i = 0; i < 9; ++i) list.put(float(i));
  list.put(std::uint32_t(100000000)).put(0).put(1).put(2);
  EXPECT_REFUSED(list.bytes(), "face 0 (byte 36 of the body): a list of 100000000 items runs past");
  EXPECT_REFUSED(ascii("ply\nformat ascii 1.0\nelement vertex 3\n" + kVertexXyz +
                       "element face 1\nproperty list uint int vertex_indices\nend_header\n"
                       "0 0 0\n1 0 0\n0 1 0\n100000000 0 1 2\n"),
                 "face 0 (line 13): a list of 100000000 items runs past the end of the line");
}

TEST(PlyImport, TruncatedAndBadBodiesAreRefused) {
  const std::vector<std::byte> strips = strip_file(false, "uchar");
  EXPECT_REFUSED(std::vector<std::byte>(strips.begin(), strips.end() - 3),
                 "tristrips 1 (byte 229 of the body): the file ends inside this entry");
  const std::string head = "ply\nformat ascii 1.0\nelement vertex 3\n" + kVertexXyz +
                           "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                           "0 0 0\n1 0 0\n0 1 0\n";
  EXPECT_REFUSED(ascii(head + "3 0 1 99\n"), "face 0 (line 13): names vertex 99 of 3 vertices");
  EXPECT_REFUSED(ascii(head + "3 0 -1 2\n"), "names vertex -1 of 3 vertices");
  EXPECT_REFUSED(ascii(head + "3 0 1\n"), "face 0 (line 13): a list of 3 items runs past the end");
  EXPECT_REFUSED(ascii(head), "face element: claims 1 entries, more than the 0 bytes left");
  EXPECT_REFUSED(ascii(head + "\n \n\n"), "face 0 (line 16): the file ends before this entry");
  EXPECT_REFUSED(ascii("ply\nformat ascii 1.0\nelement vertex 2\n" + kVertexXyz +
                       "end_header\n0 0 0\n1 1     \n"),
                 "vertex 1 (line 9): the line has too few values");
  EXPECT_REFUSED(ascii(head + "3 0 1 2.5\n"), "'2.5' is not a valid int");
  EXPECT_REFUSED(
      ascii("ply\nformat ascii 1.0\nelement vertex 1\n" + kVertexXyz + "end_header\n0 zero 0\n"),
      "vertex 0 (line 8): 'zero' is not a valid float");
  EXPECT_REFUSED(ascii("ply\nformat ascii 1.0\nelement vertex 1\nproperty uchar x\n"
                       "property float y\nproperty float z\nend_header\n256 0 0\n"),
                 "'256' is not a valid uchar");
  const std::string strip_head = "ply\nformat ascii 1.0\nelement vertex 3\n" + kVertexXyz +
                                 "element tristrips 1\nproperty list int int vertex_indices\n"
                                 "end_header\n0 0 0\n1 0 0\n0 1 0\n";
  EXPECT_REFUSED(ascii(strip_head + "4 0 1 -2 2\n"), "tristrips 0 (line 13): names vertex -2");
  EXPECT_REFUSED(ascii(strip_head + "3 0 1 3\n"), "names vertex 3 of 3 vertices");
}

TEST(PlyImport, BrokenHeadersAreRefused) {
  EXPECT_REFUSED(ascii("solid cube\n"), "not a PLY file");
  EXPECT_REFUSED(ascii("ply\nelement vertex 0\nend_header\n"), "no 'format' line");
  EXPECT_REFUSED(ascii("ply\nformat ascii 1.0\nelement vertex 0\n"), "no 'end_header' line");
  EXPECT_REFUSED(ascii("ply\nformat ascii 2.0\nend_header\n"), "header line 2: expected 'format");
  EXPECT_REFUSED(ascii("ply\nformat binary_middle_endian 1.0\nend_header\n"), "unknown format");
  EXPECT_REFUSED(ascii("ply\nformat ascii 1.0\nproperty float x\nend_header\n"),
                 "header line 3: property before any element");
  EXPECT_REFUSED(ascii("ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n"),
                 "unknown type 'quad'");
  EXPECT_REFUSED(ascii("ply\nformat ascii 1.0\nelement vertex 1\nproperty list float int x\n"
                       "end_header\n"),
                 "list count type 'float' is not an integer type");
  EXPECT_REFUSED(ascii("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                       "property float y\nend_header\n0 0\n"),
                 "vertex element: has no x, y or z property");
  EXPECT_REFUSED(ascii("ply\nformat ascii 1.0\nelement face 0\n"
                       "property list uchar int vertex_indices\nelement vertex 1\n" +
                       kVertexXyz + "end_header\n0 0 0\n"),
                 "face element: comes before the vertex element");
  EXPECT_REFUSED(ascii("ply\nformat ascii 1.0\nelement vertex 1\n" + kVertexXyz +
                       "element face 1\nproperty list uchar float vertex_indices\nend_header\n"
                       "0 0 0\n3 0 0 0\n"),
                 "face element: has vertex_indices that are not integers");
  EXPECT_REFUSED(ascii("ply\nformat ascii 1.0\nelement colour 0\nproperty uchar red\n"
                       "end_header\n"),
                 "has no vertex element");
}

// ---------------------------------------------------------------------------------------------
// The shared corpus

struct SharedPly {
  const char* path;
  std::uint64_t triangles;  // MANIFEST.md (none of these has zero-area triangles)
  std::uint64_t vertices;   // as the Assimp path kept them (joined, unused dropped)
};

constexpr SharedPly kSharedPlys[] = {
    {"assimp/PLY/Wuson.ply", 3732, 11152},    {"assimp/PLY/cube.ply", 12, 8},
    {"assimp/PLY/cube_binary.ply", 12, 8},    {"assimp/PLY/cube_uv.ply", 12, 24},
    {"assimp/PLY/float-color.ply", 1, 3},     {"assimp/PLY/points.ply", 0, 4},
    {"stanford/Lucy100k.ply", 100000, 50002}, {"stanford/bun_zipper.ply.zst", 69451, 34834},
};

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
  ASSERT_EQ(mine.meshes.size(), assimp.meshes.size());
  for (std::size_t m = 0; m < mine.meshes.size(); ++m) {
    EXPECT_EQ(mine.meshes[m].name, assimp.meshes[m].name);
    EXPECT_EQ(mine.meshes[m].vertex_count, assimp.meshes[m].vertex_count);
  }
}

// Counts from MANIFEST.md; the uncompressed files also bit for bit as Assimp reads them.
TEST(PlyImport, SharedPlysImportAsBefore) {
  KILN_REQUIRE_CORPUS();
  for (const SharedPly& expected : kSharedPlys) {
    SCOPED_TRACE(expected.path);
    const std::string path = test::mesh_path(expected.path);
    const Scene scene = import_scene({path}, 1);
    EXPECT_EQ(scene.input_triangle_count, expected.triangles);
    EXPECT_EQ(scene.triangles.size(), expected.triangles);
    EXPECT_EQ(scene.positions.size(), expected.vertices);
    if (path.ends_with(".zst")) continue;
    ImportedFile assimp;
    assimp.source = scene.sources.at(0);
    assimp.meshes = import_with_assimp(path, test::read_file(path), ".ply", true, {});
    std::vector<ImportedFile> files;
    files.push_back(std::move(assimp));
    expect_same_scene(scene, assemble_scene(std::move(files)));
  }
}

}  // namespace
}  // namespace kiln
