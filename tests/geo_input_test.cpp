// The 2D inputs in a blob: a polygon layer and a point table are written, mapped and read back
// exactly; open refuses forged offsets; verify refuses non-finite coordinates; dump shows them.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "kiln/compiler/build.hpp"
#include "kiln/formats/section_kinds.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

using format::Double2;

// Two features: a square with a square hole, and a feature of two triangles.
PolygonLayer two_features() {
  PolygonLayer layer;
  auto ring = [&](std::initializer_list<Double2> points) {
    for (const Double2& p : points) layer.vertices.push_back(p), layer.bounds.grow(p);
    layer.ring_vertices.push_back(layer.vertices.size());
  };
  ring({{0, 0}, {10, 0}, {10, 10}, {0, 10}});
  ring({{4, 4}, {4, 6}, {6, 6}, {6, 4}});
  layer.polygon_rings.push_back(2);
  layer.feature_polygons.push_back(1);
  ring({{20, 0}, {30, 0}, {25, 5}});
  layer.polygon_rings.push_back(3);
  ring({{20, 10}, {30, 10}, {25, 15.125}});
  layer.polygon_rings.push_back(4);
  layer.feature_polygons.push_back(3);
  layer.feature_polygons.push_back(3);  // a third feature, skipped as invalid
  layer.features_skipped = 1;
  layer.ids.push("01001"), layer.ids.push("7"), layer.ids.push("");
  layer.names.push("Square, with a \"hole\""), layer.names.push("Twins"), layer.names.push("");
  return layer;
}

std::vector<std::byte> blob_of(Scene scene, bool compress = false) {
  BuildOptions options;
  options.compression.enabled = compress;
  return compile_blob(scene, options);
}

TEST(GeoInput, PolygonLayerRoundTripsExactly) {
  Scene scene;
  scene.polygons = two_features();
  for (const bool compress : {false, true}) {
    const auto bytes = blob_of(scene, compress);
    const AlignedBuffer copy = test::aligned_copy(bytes);
    const Blob blob = Blob::open_memory(copy.bytes());
    blob.verify();
    EXPECT_EQ(blob.input().kind, InputKind::kPolygons2);
    EXPECT_EQ(blob.input().feature_count, 3u);
    const PolygonLayerView layer = blob.polygon_layer();
    const PolygonLayer& given = *scene.polygons;
    ASSERT_EQ(layer.vertices.size(), given.vertices.size());
    EXPECT_TRUE(std::equal(layer.vertices.begin(), layer.vertices.end(), given.vertices.begin()));
    EXPECT_TRUE(std::ranges::equal(layer.ring_vertices, given.ring_vertices));
    EXPECT_TRUE(std::ranges::equal(layer.polygon_rings, given.polygon_rings));
    EXPECT_TRUE(std::ranges::equal(layer.feature_polygons, given.feature_polygons));
    EXPECT_EQ(layer.ids[0], "01001");
    EXPECT_EQ(layer.names[0], "Square, with a \"hole\"");
    EXPECT_EQ(layer.names[2], "");
    EXPECT_EQ(layer.features_skipped, 1u);
    EXPECT_EQ(layer.bounds.max.y, 15.125);
    EXPECT_EQ(layer.ring(1).size(), 4u);
    EXPECT_THROW(blob.point_table(), BlobError);
  }
}

TEST(GeoInput, PointTableRoundTripsWithAndWithoutRowOffsets) {
  Scene scene;
  PointTable2& table = scene.points2.emplace();
  table.points = {{1.5, 2.5}, {-3, 4}, {1e-300, -1e300}};
  for (const Double2& p : table.points) table.bounds.grow(p);
  table.x_column = "lon", table.y_column = "lat";
  {
    const auto bytes = blob_of(scene);
    const AlignedBuffer copy = test::aligned_copy(bytes);
    const Blob blob = Blob::open_memory(copy.bytes());
    blob.verify();
    const PointTableView view = blob.point_table();
    EXPECT_EQ(view.feature_count(), 3u);
    EXPECT_TRUE(view.feature_points.empty());
    EXPECT_EQ(view.points[2].y, -1e300);
    EXPECT_EQ(view.x_column, "lon");
    EXPECT_TRUE(view.ids.empty());
  }
  table.feature_points = {0, 1, 1, 3};  // row 1 skipped
  table.rows_skipped = 1;
  const auto bytes = blob_of(scene);
  const AlignedBuffer copy = test::aligned_copy(bytes);
  const Blob blob = Blob::open_memory(copy.bytes());
  const PointTableView view = blob.point_table();
  EXPECT_EQ(view.feature_count(), 3u);
  EXPECT_EQ(view.feature_points[3], 3u);
  EXPECT_EQ(view.rows_skipped, 1u);
}

// The section of `kind` in `bytes` (the first).
std::uint32_t section_of(std::span<const std::byte> bytes, std::uint32_t kind) {
  const AlignedBuffer copy = test::aligned_copy(bytes);
  const Blob blob = Blob::open_memory(copy.bytes());
  for (std::uint32_t i = 0; i < blob.sections().size(); ++i)
    if (blob.sections()[i].kind == kind) return i;
  ADD_FAILURE() << "no section " << kind;
  return 0;
}

TEST(GeoInput, ForgedOffsetsAreRefusedAtOpen) {
  Scene scene;
  scene.polygons = two_features();
  const auto bytes = blob_of(scene);
  struct Case {
    std::uint32_t kind;
    std::size_t entry;
    std::uint64_t value;
    const char* says;
  };
  const Case cases[] = {
      {format::kSectionLayerRings, 1, 2, "at least 3"},        // a ring of 2 vertices
      {format::kSectionLayerRings, 0, 1, "start at 0"},        // not from 0
      {format::kSectionLayerRings, 4, 99, "end at"},           // past the vertices
      {format::kSectionLayerPolygons, 1, 0, "at least 1"},     // a polygon without a ring
      {format::kSectionLayerFeatures, 1, 5, "has"},            // decreasing
      {format::kSectionStringOffsets, 1, 1u << 20, "strings"}  // past the bytes
  };
  for (const Case& c : cases) {
    const AlignedBuffer forged =
        test::forged_copy(bytes, section_of(bytes, c.kind), c.entry * 8, c.value);
    try {
      (void)Blob::open_memory(forged.bytes());
      ADD_FAILURE() << "opened with " << format::fourcc_to_string(c.kind) << "[" << c.entry
                    << "] = " << c.value;
    } catch (const BlobError& e) {
      EXPECT_NE(std::string(e.what()).find(c.says), std::string::npos) << e.what();
    }
  }
  const double nan = std::nan("");
  const AlignedBuffer forged =
      test::forged_copy(bytes, section_of(bytes, format::kSectionLayerVertices), 16 * 5, nan);
  const Blob blob = Blob::open_memory(forged.bytes());  // open does not read coordinates
  EXPECT_THROW(blob.verify(), BlobError);
}

TEST(GeoInput, DumpShowsTheLayer) {
  Scene scene;
  scene.polygons = two_features();
  test::TempDir dir;
  test::write_file(dir.file("layer.kiln"), blob_of(scene));
  const auto text = test::run_kiln("dump " + test::quoted(dir.file("layer.kiln")));
  ASSERT_EQ(text.exit_code, 0) << text.err;
  EXPECT_NE(text.out.find("input: 2D polygon layer"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("features   3  (skipped as invalid 1"), std::string::npos);
  EXPECT_NE(text.out.find("rings      4  (holes 1)"), std::string::npos);
  const auto json = test::run_kiln("dump --json " + test::quoted(dir.file("layer.kiln")));
  ASSERT_EQ(json.exit_code, 0) << json.err;
  EXPECT_NE(json.out.find("\"polygon_layer\""), std::string::npos);
  EXPECT_NE(json.out.find("\"vertex_count\":14"), std::string::npos) << json.out;
  const auto verify = test::run_kiln("verify " + test::quoted(dir.file("layer.kiln")));
  EXPECT_EQ(verify.exit_code, 0) << verify.err;
}

}  // namespace
}  // namespace kiln
