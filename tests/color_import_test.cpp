// Colour import: vertex colours times the material's base colour, packed RGBA8 (r in the low
// byte), carried through scene assembly like positions. Expected values come from the input files
// themselves (read by hand, or written here), never from the importer.
#include <draco/compression/encode.h>
#include <draco/mesh/triangle_soup_mesh_builder.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "import_fixtures.hpp"
#include "kiln/compiler/build.hpp"
#include "kiln/compiler/import.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

using test::write_text;

constexpr std::uint32_t kWhite = 0xFFFFFFFF;

std::uint32_t rgba(std::uint32_t r, std::uint32_t g, std::uint32_t b, std::uint32_t a) {
  return r | g << 8 | b << 16 | a << 24;
}

// The colours of scene mesh `m`'s vertices.
std::vector<std::uint32_t> mesh_colors(const Scene& scene, std::size_t m) {
  const SceneMesh& mesh = scene.meshes.at(m);
  return {scene.colors.begin() + std::ptrdiff_t(mesh.first_vertex),
          scene.colors.begin() + std::ptrdiff_t(mesh.first_vertex + mesh.vertex_count)};
}

void expect_all(const std::vector<std::uint32_t>& colors, std::uint32_t expected) {
  for (std::size_t i = 0; i < colors.size(); ++i)
    EXPECT_EQ(colors[i], expected) << "vertex " << i << ": 0x" << std::hex << colors[i];
}

// --- Assimp ---------------------------------------------------------------------------------

// float-color.ply gives each of its 3 vertices "red green blue alpha" = 0 0 1 1; PLY materials
// in Assimp are unnamed defaults, so the vertex colour is all there is.
TEST(ColorImport, PlyFloatVertexColors) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({test::mesh_path("assimp/PLY/float-color.ply")}, 1);
  ASSERT_EQ(scene.positions.size(), 3u);
  ASSERT_EQ(scene.colors.size(), 3u);
  expect_all(scene.colors, rgba(0, 0, 255, 255));
}

// Assimp invents a material for files that have none (STL, OFF, PLY, an OBJ without .mtl, an
// OBJ `usemtl` with no library as in box.obj): none of them is a colour.
TEST(ColorImport, InventedMaterialsGiveNoColors) {
  KILN_REQUIRE_CORPUS();
  for (const char* mesh :
       {"assimp/OBJ/box.obj", "classic/teapot.obj", "assimp/PLY/cube.ply", "assimp/OFF/Cube.off",
        "assimp/STL/triangle.stl", "assimp/3MF/box.3mf"}) {
    SCOPED_TRACE(mesh);
    const Scene scene = import_scene({test::mesh_path(mesh)}, 1);
    EXPECT_FALSE(scene.positions.empty());
    EXPECT_TRUE(scene.colors.empty());
  }
}

// concave_polygon.mtl: "Kd 0.141176 0.184314 0.411765", used by every face.
TEST(ColorImport, ObjMtlKdFromCorpus) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({test::mesh_path("assimp/OBJ/concave_polygon.obj")}, 1);
  ASSERT_FALSE(scene.positions.empty());
  ASSERT_EQ(scene.colors.size(), scene.positions.size());
  // 0.141176 * 255 = 35.99988, 0.184314 * 255 = 47.00007, 0.411765 * 255 = 105.000075.
  expect_all(scene.colors, rgba(36, 47, 105, 255));
}

TEST(ColorImport, ObjWithoutMtlHasNoColors) {
  test::TempDir dir;
  write_text(dir.file("plain.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const Scene scene = import_scene({dir.file("plain.obj")}, 1);
  EXPECT_EQ(scene.positions.size(), 3u);
  EXPECT_TRUE(scene.colors.empty());
}

// Faces before any usemtl use Assimp's DefaultMaterial (no colour: white in a coloured scene);
// "blue" has a Kd; "nowhere" is in no library (Assimp invents a grey copy: no colour).
TEST(ColorImport, ObjMtlKdPerMaterial) {
  test::TempDir dir;
  write_text(dir.file("colors.mtl"), "newmtl blue\nKa 0 0 0\nKd 0.2 0.4 0.6\nNs 10\n");
  write_text(dir.file("parts.obj"),
             "mtllib colors.mtl\n"
             "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 1 1 1\n"
             "f 1 2 3\n"
             "usemtl blue\nf 1 2 4\n"
             "usemtl nowhere\nf 1 2 5\n");
  const Scene scene = import_scene({dir.file("parts.obj")}, 1);
  ASSERT_EQ(scene.colors.size(), scene.positions.size());
  ASSERT_EQ(scene.triangles.size(), 3u);
  std::size_t blue_meshes = 0;
  for (std::size_t m = 0; m < scene.meshes.size(); ++m) {
    // Which face a mesh holds is told by its third corner: (0,0,1) only in the "blue" face.
    const SceneMesh& mesh = scene.meshes[m];
    bool has_blue_corner = false;
    for (std::uint64_t v = mesh.first_vertex; v < mesh.first_vertex + mesh.vertex_count; ++v)
      has_blue_corner |=
          scene.positions[v].x == 0 && scene.positions[v].y == 0 && scene.positions[v].z == 1;
    blue_meshes += has_blue_corner;
    // 0.2 * 255 = 51, 0.4 * 255 = 102, 0.6 * 255 = 153.
    expect_all(mesh_colors(scene, m), has_blue_corner ? rgba(51, 102, 153, 255) : kWhite);
  }
  EXPECT_EQ(blue_meshes, 1u);
}

// --- glTF -----------------------------------------------------------------------------------

std::string base64(const std::vector<std::uint8_t>& bytes) {
  static const char* digits = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    const std::uint32_t n = std::uint32_t(bytes[i]) << 16 |
                            (i + 1 < bytes.size() ? std::uint32_t(bytes[i + 1]) << 8 : 0) |
                            (i + 2 < bytes.size() ? bytes[i + 2] : 0);
    out += digits[n >> 18 & 63];
    out += digits[n >> 12 & 63];
    out += i + 1 < bytes.size() ? digits[n >> 6 & 63] : '=';
    out += i + 2 < bytes.size() ? digits[n & 63] : '=';
  }
  return out;
}

template <class T>
void append(std::vector<std::uint8_t>& out, const std::vector<T>& values) {
  const auto* p = reinterpret_cast<const std::uint8_t*>(values.data());
  out.insert(out.end(), p, p + values.size() * sizeof(T));
}

struct ColorAccessor {
  int component_type;  // 5121 unsigned byte, 5123 unsigned short, 5126 float
  const char* type;    // "VEC3" or "VEC4"
  std::size_t count;
  std::vector<std::uint8_t> bytes;
};

// One triangle (0,0,0) (1,0,0) (0,1,0), optionally with COLOR_0 and a material ("" for none).
std::string triangle_gltf(const ColorAccessor* color, const std::string& material) {
  std::vector<std::uint8_t> buffer;
  append(buffer, std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0});
  std::string attributes = R"("POSITION":0)";
  std::string views = R"({"buffer":0,"byteOffset":0,"byteLength":36})";
  std::string accessors =
      R"({"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]})";
  if (color != nullptr) {
    attributes += R"(,"COLOR_0":1)";
    views +=
        R"(,{"buffer":0,"byteOffset":36,"byteLength":)" + std::to_string(color->bytes.size()) + "}";
    accessors += R"(,{"bufferView":1,"componentType":)" + std::to_string(color->component_type) +
                 (color->component_type == 5126 ? "" : R"(,"normalized":true)") + R"(,"count":)" +
                 std::to_string(color->count) + R"(,"type":")" + color->type + R"("})";
    buffer.insert(buffer.end(), color->bytes.begin(), color->bytes.end());
  }
  std::string primitive = R"({"attributes":{)" + attributes + "}";
  std::string materials;
  if (!material.empty()) {
    primitive += R"(,"material":0)";
    materials = R"("materials":[)" + material + "],";
  }
  primitive += "}";
  return R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],)"
         R"("meshes":[{"primitives":[)" +
         primitive + "]}]," + materials + R"("buffers":[{"byteLength":)" +
         std::to_string(buffer.size()) + R"(,"uri":"data:application/octet-stream;base64,)" +
         base64(buffer) + R"("}],"bufferViews":[)" + views + R"(],"accessors":[)" + accessors +
         "]}";
}

Scene import_gltf_text(const test::TempDir& dir, const std::string& text) {
  write_text(dir.file("mesh.gltf"), text);
  return import_scene({dir.file("mesh.gltf")}, 1);
}

// Normalized unsigned bytes times baseColorFactor [0.6, 1, 0.2, 1]: 255 * 0.6 = 153,
// 10 * 0.6 = 6, 30 * 0.2 = 6.
TEST(ColorImport, GltfByteColorsTimesBaseColorFactor) {
  test::TempDir dir;
  const ColorAccessor color{5121, "VEC4", 3, {255, 0, 0, 255, 0, 255, 0, 128, 10, 20, 30, 255}};
  const Scene scene = import_gltf_text(
      dir, triangle_gltf(&color, R"({"pbrMetallicRoughness":{"baseColorFactor":[0.6,1,0.2,1]}})"));
  ASSERT_EQ(scene.colors.size(), 3u);
  EXPECT_EQ(scene.colors[0], rgba(153, 0, 0, 255));
  EXPECT_EQ(scene.colors[1], rgba(0, 255, 0, 128));
  EXPECT_EQ(scene.colors[2], rgba(6, 20, 6, 255));
}

// Float VEC3 colours, no material: clamped to [0, 1], alpha 1; 0.5 * 255 = 127.5 rounds up.
TEST(ColorImport, GltfFloatVec3Colors) {
  test::TempDir dir;
  ColorAccessor color{5126, "VEC3", 3, {}};
  append(color.bytes, std::vector<float>{1, 0, 0, 0.2f, 0.4f, 0.6f, 2, -1, 0.5f});
  const Scene scene = import_gltf_text(dir, triangle_gltf(&color, ""));
  ASSERT_EQ(scene.colors.size(), 3u);
  EXPECT_EQ(scene.colors[0], rgba(255, 0, 0, 255));
  EXPECT_EQ(scene.colors[1], rgba(51, 102, 153, 255));
  EXPECT_EQ(scene.colors[2], rgba(255, 0, 128, 255));
}

// Normalized unsigned shorts: 65535 = 1, 32768 / 65535 * 255 = 127.5019 -> 128.
TEST(ColorImport, GltfShortColors) {
  test::TempDir dir;
  ColorAccessor color{5123, "VEC4", 3, {}};
  append(color.bytes,
         std::vector<std::uint16_t>{65535, 0, 32768, 65535, 0, 0, 0, 0, 257, 514, 771, 65535});
  const Scene scene = import_gltf_text(dir, triangle_gltf(&color, ""));
  ASSERT_EQ(scene.colors.size(), 3u);
  EXPECT_EQ(scene.colors[0], rgba(255, 0, 128, 255));
  EXPECT_EQ(scene.colors[1], rgba(0, 0, 0, 0));
  EXPECT_EQ(scene.colors[2], rgba(1, 2, 3, 255));  // 257 / 65535 = 1 / 255
}

// A material without baseColorFactor has the default [1,1,1,1]: a colour (white); no material
// at all: no colour.
TEST(ColorImport, GltfMaterialPresenceDecides) {
  test::TempDir dir;
  const Scene with_material = import_gltf_text(dir, triangle_gltf(nullptr, "{}"));
  ASSERT_EQ(with_material.colors.size(), 3u);
  expect_all(with_material.colors, kWhite);
  const Scene without = import_gltf_text(dir, triangle_gltf(nullptr, ""));
  EXPECT_EQ(without.positions.size(), 3u);
  EXPECT_TRUE(without.colors.empty());
}

TEST(ColorImport, GltfMalformedColorsAreRefused) {
  test::TempDir dir;
  ColorAccessor short_count{5121, "VEC4", 2, {255, 0, 0, 255, 0, 255, 0, 255}};
  test::expect_import_error([&] { import_gltf_text(dir, triangle_gltf(&short_count, "")); },
                            "COLOR_0");
  ColorAccessor nan{5126, "VEC3", 3, {}};
  append(nan.bytes,
         std::vector<float>{1, 0, 0, std::numeric_limits<float>::quiet_NaN(), 0, 0, 0, 0, 1});
  test::expect_import_error([&] { import_gltf_text(dir, triangle_gltf(&nan, "")); }, "non-finite");
  ColorAccessor signed_bytes{5120, "VEC4", 3, std::vector<std::uint8_t>(12, 1)};
  test::expect_import_error([&] { import_gltf_text(dir, triangle_gltf(&signed_bytes, "")); },
                            "COLOR_0");
  ColorAccessor vec2{5126, "VEC2", 3, std::vector<std::uint8_t>(24, 0)};
  test::expect_import_error([&] { import_gltf_text(dir, triangle_gltf(&vec2, "")); }, "COLOR_0");
  std::string bad_material = triangle_gltf(nullptr, "{}");
  bad_material.replace(bad_material.find(R"("material":0)"), 12, R"("material":3)");
  test::expect_import_error([&] { import_gltf_text(dir, bad_material); }, "material 3");
}

// Box_Draco.glb's one material: "baseColorFactor": [0.800000011920929, 0, 0, 1] (204 = 0.8 * 255).
TEST(ColorImport, GltfBaseColorFactorFromCorpus) {
  KILN_REQUIRE_CORPUS();
  const Scene scene =
      import_scene({test::mesh_path("gltf/Box-glTF-Draco-Binary/Box_Draco.glb")}, 1);
  ASSERT_FALSE(scene.positions.empty());
  ASSERT_EQ(scene.colors.size(), scene.positions.size());
  expect_all(scene.colors, rgba(204, 0, 0, 255));
}

// BoxTextured's material has only a texture: its factor is the default, white.
TEST(ColorImport, GltfTexturedMaterialIsWhite) {
  KILN_REQUIRE_CORPUS();
  const Scene scene =
      import_scene({test::mesh_path("assimp/glTF2/BoxTextured-glTF/BoxTextured.gltf")}, 1);
  ASSERT_EQ(scene.colors.size(), scene.positions.size());
  expect_all(scene.colors, kWhite);
}

// --- Draco ----------------------------------------------------------------------------------

// Two triangles over four distinct corners, COLOR given per corner as raw `bytes_per_corner`,
// encoded by Draco's own encoder. Draco may reorder points, so colours are checked by position.
struct DracoCase {
  draco::DataType type;
  int components;
  std::vector<std::vector<std::uint8_t>> corner_colors;  // for corners 0..3
};

const float kDracoCorners[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};

void write_draco(const std::string& path, const DracoCase& c) {
  draco::TriangleSoupMeshBuilder builder;
  builder.Start(2);
  const int position =
      builder.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
  const int color = builder.AddAttribute(draco::GeometryAttribute::COLOR, std::int8_t(c.components),
                                         c.type, true);
  const int faces[2][3] = {{0, 1, 2}, {2, 1, 3}};
  for (int f = 0; f < 2; ++f) {
    const int* v = faces[f];
    builder.SetAttributeValuesForFace(position, draco::FaceIndex(f), kDracoCorners[v[0]],
                                      kDracoCorners[v[1]], kDracoCorners[v[2]]);
    builder.SetAttributeValuesForFace(color, draco::FaceIndex(f), c.corner_colors[v[0]].data(),
                                      c.corner_colors[v[1]].data(), c.corner_colors[v[2]].data());
  }
  const auto mesh = builder.Finalize();
  ASSERT_NE(mesh, nullptr);
  draco::Encoder encoder;
  draco::EncoderBuffer buffer;
  ASSERT_TRUE(encoder.EncodeMeshToBuffer(*mesh, &buffer).ok());
  test::write_file(path, std::as_bytes(std::span<const char>(buffer.data(), buffer.size())));
}

void expect_draco_colors(const DracoCase& c, const std::uint32_t (&expected)[4]) {
  test::TempDir dir;
  write_draco(dir.file("mesh.drc"), c);
  const Scene scene = import_scene({dir.file("mesh.drc")}, 1);
  ASSERT_EQ(scene.positions.size(), 4u);
  ASSERT_EQ(scene.colors.size(), 4u);
  for (std::size_t v = 0; v < 4; ++v) {
    int corner = -1;
    for (int k = 0; k < 4; ++k)
      if (scene.positions[v].x == kDracoCorners[k][0] &&
          scene.positions[v].y == kDracoCorners[k][1])
        corner = k;
    ASSERT_GE(corner, 0);
    EXPECT_EQ(scene.colors[v], expected[corner]) << "corner " << corner;
  }
}

std::vector<std::uint8_t> float_bytes(std::vector<float> values) {
  std::vector<std::uint8_t> out;
  append(out, values);
  return out;
}

TEST(ColorImport, DracoByteRgbColors) {
  const DracoCase c{draco::DT_UINT8, 3, {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}, {10, 20, 30}}};
  const std::uint32_t expected[4] = {rgba(255, 0, 0, 255), rgba(0, 255, 0, 255),
                                     rgba(0, 0, 255, 255), rgba(10, 20, 30, 255)};
  expect_draco_colors(c, expected);
}

TEST(ColorImport, DracoFloatRgbaColors) {
  const DracoCase c{draco::DT_FLOAT32,
                    4,
                    {float_bytes({1, 0, 0, 1}), float_bytes({0.2f, 0.4f, 0.6f, 0}),
                     float_bytes({2, -1, 0.5f, 1}), float_bytes({0, 0, 1, 0.6f})}};
  const std::uint32_t expected[4] = {rgba(255, 0, 0, 255), rgba(51, 102, 153, 0),
                                     rgba(255, 0, 128, 255), rgba(0, 0, 255, 153)};
  expect_draco_colors(c, expected);
}

TEST(ColorImport, DracoMalformedColorsAreRefused) {
  test::TempDir dir;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const DracoCase not_finite{draco::DT_FLOAT32,
                             3,
                             {float_bytes({1, 0, 0}), float_bytes({nan, 0, 0}),
                              float_bytes({0, 1, 0}), float_bytes({0, 0, 1})}};
  write_draco(dir.file("nan.drc"), not_finite);
  test::expect_import_error([&] { import_scene({dir.file("nan.drc")}, 1); }, "Draco COLOR");
  const DracoCase two_components{draco::DT_UINT8, 2, {{1, 2}, {3, 4}, {5, 6}, {7, 8}}};
  write_draco(dir.file("two.drc"), two_components);
  test::expect_import_error([&] { import_scene({dir.file("two.drc")}, 1); }, "Draco COLOR");
}

// --- Scene assembly -------------------------------------------------------------------------

// A coloured mesh beside an uncoloured one, in either order: the uncoloured one's vertices are
// white, the coloured one's keep their colours (float-color.ply: all 0 0 1 1).
TEST(ColorImport, MixedSceneGivesWhiteToUncoloredMeshes) {
  KILN_REQUIRE_CORPUS();
  const std::string colored = test::mesh_path("assimp/PLY/float-color.ply");
  const std::string plain = test::mesh_path("classic/teapot.obj");
  const Scene first = import_scene({colored, plain}, 2);
  ASSERT_EQ(first.meshes.size(), 2u);
  ASSERT_EQ(first.colors.size(), first.positions.size());
  expect_all(mesh_colors(first, 0), rgba(0, 0, 255, 255));
  expect_all(mesh_colors(first, 1), kWhite);
  EXPECT_GT(first.meshes[1].vertex_count, 0u);

  const Scene second = import_scene({plain, colored}, 2);
  ASSERT_EQ(second.colors.size(), second.positions.size());
  expect_all(mesh_colors(second, 0), kWhite);
  expect_all(mesh_colors(second, 1), rgba(0, 0, 255, 255));
  EXPECT_EQ(second.meshes[1].vertex_count, 3u);
}

ImportedMesh mesh_of(std::vector<format::Float3> positions, std::vector<format::Triangle> triangles,
                     std::vector<std::uint32_t> colors) {
  ImportedMesh mesh;
  mesh.name = "m";
  mesh.positions = std::move(positions);
  mesh.triangles = std::move(triangles);
  mesh.colors = std::move(colors);
  return mesh;
}

// Colours follow their vertices through the dropping of degenerate triangles and unused vertices.
TEST(ColorImport, AssemblyCompactsColorsLikePositions) {
  ImportedFile file;
  file.source.path = "memory";
  // Vertex 1 is unused; triangle (3, 4, 3) is degenerate, so 3 and 4 go too.
  file.meshes.push_back(
      mesh_of({{0, 0, 0}, {9, 9, 9}, {1, 0, 0}, {0, 1, 0}, {5, 5, 5}, {0, 0, 1}},
              {{{0, 2, 3}}, {{3, 4, 3}}, {{0, 2, 5}}},
              {0x11111111, 0x22222222, 0x33333333, 0x44444444, 0x55555555, 0x66666666}));
  file.meshes.push_back(mesh_of({{0, 0, 2}, {1, 0, 2}, {0, 1, 2}}, {{{0, 1, 2}}}, {}));
  std::vector<ImportedFile> files;
  files.push_back(std::move(file));
  const Scene scene = assemble_scene(std::move(files));
  ASSERT_EQ(scene.positions.size(), 7u);
  const std::vector<std::uint32_t> expected = {0x11111111, 0x33333333, 0x44444444, 0x66666666,
                                               kWhite,     kWhite,     kWhite};
  EXPECT_EQ(scene.colors, expected);
}

// A coloured mesh that keeps no vertex adds no colours; a wrong colour count is refused.
TEST(ColorImport, AssemblyColorEdgeCases) {
  {
    ImportedFile file;
    file.meshes.push_back(mesh_of({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{{0, 1, 2}}}, {}));
    file.meshes.push_back(
        mesh_of({{0, 0, 0}, {1, 0, 0}}, {{{0, 1, 1}}}, {0x12345678, 0x12345678}));  // degenerate
    std::vector<ImportedFile> files;
    files.push_back(std::move(file));
    const Scene scene = assemble_scene(std::move(files));
    EXPECT_EQ(scene.positions.size(), 3u);
    EXPECT_TRUE(scene.colors.empty());
  }
  ImportedFile file;
  file.source.path = "memory";
  file.meshes.push_back(mesh_of({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{{0, 1, 2}}}, {kWhite}));
  std::vector<ImportedFile> files;
  files.push_back(std::move(file));
  test::expect_import_error([&] { assemble_scene(std::move(files)); }, "colours");
}

}  // namespace
}  // namespace kiln
