// The 2D inputs: GeoJSON and CSV point tables into PolygonLayer / PointTable2, their error lines,
// --skip-invalid, .zst, hostile JSON, and the shared geo data (../shared/data/geo).
#include <gtest/gtest.h>
#include <zstd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "kiln/compiler/build_cache.hpp"
#include "kiln/compiler/csv_reader.hpp"
#include "kiln/compiler/geo_import.hpp"
#include "kiln/runtime/blob.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

using format::Double2;

std::string geo_dir() {
  return std::string(KILN_MESH_DIR) + "/../geo";
}

#define KILN_REQUIRE_GEO()                                                                \
  do {                                                                                    \
    if (!std::filesystem::is_directory(geo_dir()))                                        \
      GTEST_SKIP() << "geo data " << geo_dir() << " is absent: shared-data test skipped"; \
  } while (0)

GeoImportOptions csv_options(std::string x, std::string y, bool skip = false) {
  GeoImportOptions o;
  o.x_column = std::move(x), o.y_column = std::move(y), o.skip_invalid = skip;
  return o;
}

GeoImportOptions skipping() {
  GeoImportOptions o;
  o.skip_invalid = true;
  return o;
}
GeoImportOptions naming(std::string property) {
  GeoImportOptions o;
  o.name_property = std::move(property);
  return o;
}

// The one-line message `f` throws as ImportError.
std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const ImportError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    return what;
  }
  ADD_FAILURE() << "no ImportError";
  return {};
}

std::string geojson_error(const std::string& text, const GeoImportOptions& o = {}) {
  return error_of([&] { import_geojson("in.geojson", text, o); });
}
std::string csv_error(const std::string& text, const GeoImportOptions& o) {
  return error_of([&] { import_csv_points("in.csv", text, o); });
}

std::string feature(const std::string& geometry, const std::string& id = "",
                    const std::string& properties = "{}") {
  return R"({"type":"Feature",)" + (id.empty() ? "" : R"("id":)" + id + ",") + R"("properties":)" +
         properties + R"(,"geometry":)" + geometry + "}";
}
std::string collection(const std::vector<std::string>& features) {
  std::string s = R"({"type":"FeatureCollection","features":[)";
  for (std::size_t i = 0; i < features.size(); ++i) s += (i ? "," : "") + features[i];
  return s + "]}";
}

constexpr const char* kSquare = "[[0,0],[4,0],[4,4],[0,4],[0,0]]";
constexpr const char* kHole = "[[1,1],[1,2],[2,2],[2,1],[1,1]]";

TEST(GeoJsonImport, PolygonsHolesAndMultiPolygons) {
  const std::string text = collection({
      feature(std::string(R"({"type":"Polygon","coordinates":[)") + kSquare + "," + kHole + "]}",
              R"("01001")", R"({"name":"Square"})"),
      feature(std::string(R"({"type":"MultiPolygon","coordinates":[[)") + kSquare + "],[" +
                  "[[10,10,5],[11,10,5],[11,11,5],[10,10,5]]" + "]]}",
              "7.50", R"({"name":42})"),
      feature("null", "", R"({"other":"x"})"),
  });
  const GeoInput in = import_geojson("in.geojson", text, {});
  ASSERT_TRUE(in.polygons);
  EXPECT_FALSE(in.points);
  const PolygonLayer& l = *in.polygons;
  EXPECT_EQ(l.feature_count(), 3u);
  EXPECT_EQ(l.feature_polygons, (std::vector<std::uint64_t>{0, 1, 3, 3}));
  EXPECT_EQ(l.polygon_rings, (std::vector<std::uint64_t>{0, 2, 3, 4}));
  EXPECT_EQ(l.ring_vertices, (std::vector<std::uint64_t>{0, 4, 8, 12, 15}));
  EXPECT_EQ(l.vertices[4], (Double2{1, 1}));
  EXPECT_EQ(l.vertices[14], (Double2{11, 11}));  // the altitude is ignored
  EXPECT_EQ(l.ids[0], "01001");                  // a string id stays as written
  EXPECT_EQ(l.ids[1], "7.50");                   // a number id as written
  EXPECT_EQ(l.ids[2], "");
  EXPECT_EQ(l.names[0], "Square");
  EXPECT_EQ(l.names[1], "42");
  EXPECT_EQ(l.names[2], "");
  EXPECT_EQ(l.name_property, "name");
  EXPECT_EQ(in.null_geometries, 1u);
  EXPECT_EQ(l.features_skipped, 0u);
  EXPECT_EQ(l.bounds.min, (Double2{0, 0}));
  EXPECT_EQ(l.bounds.max, (Double2{11, 11}));
}

TEST(GeoJsonImport, CoordinatesAreExactDoubles) {
  const std::string text =
      R"({"type":"Polygon","coordinates":[[[0.1,-114.05190414404143],[1e-320,2],)"
      R"([1.7976931348623157e308,3],[123456789012345678901234567890,4],[0.1,-114.05190414404143]]]})";
  const PolygonLayer l = *import_geojson("in.geojson", text, {}).polygons;
  ASSERT_EQ(l.vertices.size(), 4u);
  EXPECT_EQ(l.vertices[0], (Double2{0.1, -114.05190414404143}));
  EXPECT_EQ(l.vertices[1].x, 1e-320);
  EXPECT_EQ(l.vertices[2].x, 1.7976931348623157e308);
  EXPECT_EQ(l.vertices[3].x, 123456789012345678901234567890.0);
}

TEST(GeoJsonImport, BareFeatureAndGeometryAndKeyOrder) {
  // "type" after "coordinates", a bare Feature, a bare geometry.
  const std::string late_type =
      std::string(R"({"features":[{"geometry":{"coordinates":[)") + kSquare +
      R"(],"type":"Polygon"},"properties":{"name":"a"},"type":"Feature","id":3}],"type":"FeatureCollection"})";
  const PolygonLayer a = *import_geojson("in.geojson", late_type, {}).polygons;
  EXPECT_EQ(a.feature_count(), 1u);
  EXPECT_EQ(a.ids[0], "3");
  EXPECT_EQ(a.names[0], "a");
  const PolygonLayer b =
      *import_geojson("in.geojson",
                      feature(std::string(R"({"type":"Polygon","coordinates":[)") + kSquare + "]}",
                              "1", R"({"NAME":"b"})"),
                      naming("NAME"))
           .polygons;
  EXPECT_EQ(b.names[0], "b");
  EXPECT_EQ(b.name_property, "NAME");
  // A UTF-8 byte order mark is skipped.
  const GeoInput c = import_geojson("in.json",
                                    "\xEF\xBB\xBF"
                                    R"({"type":"Point","coordinates":[1,2]})",
                                    {});
  ASSERT_TRUE(c.points);
  EXPECT_EQ(c.points->points, (std::vector<Double2>{{1, 2}}));
  EXPECT_TRUE(c.points->feature_points.empty());  // point i is feature i
}

TEST(GeoJsonImport, PointsAndMultiPoints) {
  const std::string text = collection({
      feature(R"({"type":"Point","coordinates":[1,2]})", R"("a")", R"({"name":"p"})"),
      feature(R"({"type":"MultiPoint","coordinates":[[3,4],[5,6,7]]})", R"("b")"),
      feature("null", R"("c")"),
  });
  const GeoInput in = import_geojson("in.geojson", text, {});
  ASSERT_TRUE(in.points);
  const PointTable2& t = *in.points;
  EXPECT_EQ(t.points, (std::vector<Double2>{{1, 2}, {3, 4}, {5, 6}}));
  EXPECT_EQ(t.feature_points, (std::vector<std::uint64_t>{0, 1, 3, 3}));
  EXPECT_EQ(t.feature_count(), 3u);
  EXPECT_EQ(t.ids[2], "c");
  EXPECT_EQ(t.names[0], "p");
  EXPECT_EQ(t.name_property, "name");
  EXPECT_EQ(t.x_column, "");
  EXPECT_EQ(t.bounds.min, (Double2{1, 2}));
  EXPECT_EQ(t.bounds.max, (Double2{5, 6}));
}

TEST(GeoJsonImport, DegenerateRingsAreDroppedAndCounted) {
  // A zero-area hole is dropped; a polygon whose outer ring is zero-area goes with its holes;
  // the feature stays (its other polygon, or none).
  const std::string sliver = "[[5,5],[6,6],[5,5],[5,5]]";
  const std::string text = collection({
      feature(std::string(R"({"type":"Polygon","coordinates":[)") + kSquare + "," + sliver + "]}"),
      feature(std::string(R"({"type":"MultiPolygon","coordinates":[[)") + sliver + "," + kHole +
              "],[" + kSquare + "]]}"),
      feature(R"({"type":"Polygon","coordinates":[)" + sliver + "]}"),
  });
  const GeoInput in = import_geojson("in.geojson", text, {});
  const PolygonLayer& l = *in.polygons;
  EXPECT_EQ(in.degenerate_rings_dropped, 3u);
  EXPECT_EQ(l.feature_polygons, (std::vector<std::uint64_t>{0, 1, 2, 2}));
  EXPECT_EQ(l.polygon_rings, (std::vector<std::uint64_t>{0, 1, 2}));
  EXPECT_EQ(l.vertices.size(), 8u);
  EXPECT_EQ(l.features_skipped, 0u);
}

TEST(GeoJsonImport, BrokenFeaturesAreOneLine) {
  const auto poly = [](const std::string& rings) {
    return collection(
        {feature(std::string(R"({"type":"Polygon","coordinates":[)") + kSquare + "]}"),
         feature(R"({"type":"Polygon","coordinates":)" + rings + "}", "\"X1\"")});
  };
  EXPECT_EQ(geojson_error(poly("[[[0,0],[1,0],[1,1],[0,1]]]")),
            "in.geojson: feature 1 (id X1): polygon 0, ring 0 is not closed: it starts at (0, 0) "
            "and ends at (0, 1)");
  EXPECT_EQ(geojson_error(poly("[[[0,0],[1,0],[0,0]]]")),
            "in.geojson: feature 1 (id X1): polygon 0, ring 0 has 3 points; a closed ring needs "
            "at least 4 (the first repeated last)");
  // A number beyond the double range is refused by the JSON parser itself (not skippable).
  EXPECT_EQ(geojson_error(poly("[[[0,0],[1,0],\n[1,1e999],[0,0]]]"), skipping()),
            "in.geojson: not valid JSON: number overflow parsing '1e999' at line 2 (in feature "
            "1)");
  EXPECT_EQ(geojson_error(poly("[[[0,0],[1],[1,1],[0,0]]]")),
            "in.geojson: feature 1 (id X1): polygon 0, ring 0, point 1 has 1 coordinates, not 2");
  EXPECT_EQ(geojson_error(poly("[[[0,0],[1,\"a\"],[1,1],[0,0]]]")),
            "in.geojson: feature 1 (id X1): polygon 0, ring 0, point 1 holds something other "
            "than numbers");
  EXPECT_EQ(geojson_error(poly("[[0,0]]")),
            "in.geojson: feature 1 (id X1): polygon 0, ring 0, point 0 is not an array");
  EXPECT_EQ(geojson_error(poly("7")),
            "in.geojson: feature 1 (id X1): its coordinates are not an array");
  EXPECT_EQ(
      geojson_error(collection({feature(R"({"type":"LineString","coordinates":[[0,0],[1,1]]})")})),
      "in.geojson: feature 0: a geometry of type 'LineString' is not supported (only "
      "Polygon, MultiPolygon, Point, MultiPoint)");
  EXPECT_EQ(
      geojson_error(collection({feature(R"({"type":"GeometryCollection","geometries":[]})")})),
      "in.geojson: feature 0: a GeometryCollection is not supported (only Polygon, "
      "MultiPolygon, Point, MultiPoint)");
  EXPECT_EQ(geojson_error(collection({feature(R"({"type":"MultiPolygon","coordinates":[[]]})")})),
            "in.geojson: feature 0: polygon 0 has no ring");
  EXPECT_EQ(geojson_error(collection({feature(R"({"type":"Point","coordinates":[1,2]})", "{}")})),
            "in.geojson: feature 0: its id is not a string or number");
  EXPECT_EQ(geojson_error(collection(
                {feature(R"({"type":"Point","coordinates":[1,2]})", "", R"({"name":[1]})")})),
            "in.geojson: feature 0: its property 'name' is an array, not a string or number");
  EXPECT_EQ(geojson_error(collection({"3"})), "in.geojson: feature 0: is not an object");
  // Text from the file stays on one line.
  EXPECT_EQ(geojson_error(collection({feature(R"({"type":"Line\nString"})", R"("a\nb")")})),
            "in.geojson: feature 0 (id a?b): a geometry of type 'Line?String' is not supported "
            "(only Polygon, MultiPolygon, Point, MultiPoint)");
  EXPECT_EQ(geojson_error(collection({R"({"type":"Feeture","geometry":null})"})),
            "in.geojson: feature 0: its type is 'Feeture', not 'Feature'");
}

TEST(GeoJsonImport, FileLevelErrorsAreOneLine) {
  EXPECT_EQ(geojson_error(collection(
                {feature(R"({"type":"Polygon","coordinates":[)" + std::string(kSquare) + "]}"),
                 feature(R"({"type":"Point","coordinates":[1,2]})", "9")})),
            "in.geojson: feature 1 (id 9): a Point in a layer of polygons (feature 0 is a "
            "Polygon): a layer holds polygons or points, not both");
  // Mixing is refused even with --skip-invalid: it is not one broken feature.
  EXPECT_NE(geojson_error(collection({feature(R"({"type":"Point","coordinates":[1,2]})"),
                                      feature(R"({"type":"Polygon","coordinates":[]})")}),
                          skipping())
                .find("not both"),
            std::string::npos);
  EXPECT_EQ(geojson_error(collection({feature("null")})),
            "in.geojson: no Polygon, MultiPolygon, Point or MultiPoint geometry in 1 features");
  EXPECT_EQ(geojson_error("[1,2]"),
            "in.geojson: not GeoJSON: the top level is an array, not an "
            "object");
  EXPECT_EQ(geojson_error(R"({"features":[]})"),
            "in.geojson: not GeoJSON: an object with \"features\" whose type is '', not "
            "'FeatureCollection'");
  EXPECT_EQ(geojson_error(R"({"type":"FeatureCollection"})"),
            "in.geojson: not GeoJSON: a FeatureCollection with no \"features\" array");
  EXPECT_EQ(geojson_error(R"({"type":"Feature","geometry":{"type":"Point"}})"),
            "in.geojson: feature 0: the Point has no \"coordinates\"");
  EXPECT_EQ(geojson_error("{\"type\":\n\"Polygon\",]"),
            "in.geojson: not valid JSON: parse error at line 2, column 11: syntax error while "
            "parsing object key - unexpected ']'; expected string literal");
  EXPECT_EQ(geojson_error(""),
            "in.geojson: not valid JSON: parse error at line 1, column 1: syntax error while "
            "parsing value - unexpected end of input; expected '[', '{', or a literal");
}

TEST(GeoJsonImport, SkipInvalidKeepsIndices) {
  const std::string text = collection({
      feature(R"({"type":"Polygon","coordinates":[)" + std::string(kSquare) + "]}", "1"),
      feature(R"({"type":"Polygon","coordinates":[[[0,0],[1,0],[1,1],[0,1]]]})", "2"),
      feature(R"({"type":"Polygon","coordinates":[)" + std::string(kSquare) + "," + kHole +
                  ",[[0,0],[1,0]]]}",
              "3", R"({"name":"three"})"),
      feature(R"({"type":"MultiPolygon","coordinates":[[)" + std::string(kSquare) + "]]}", "4"),
  });
  const PolygonLayer l = *import_geojson("in.geojson", text, skipping()).polygons;
  EXPECT_EQ(l.features_skipped, 2u);
  EXPECT_EQ(l.feature_polygons, (std::vector<std::uint64_t>{0, 1, 1, 1, 2}));
  EXPECT_EQ(l.polygon_rings, (std::vector<std::uint64_t>{0, 1, 2}));
  EXPECT_EQ(l.ring_vertices, (std::vector<std::uint64_t>{0, 4, 8}));
  EXPECT_EQ(l.ids[2], "3");  // a dropped feature keeps its id and name
  EXPECT_EQ(l.names[2], "three");
  EXPECT_EQ(l.ids[3], "4");
}

TEST(GeoJsonImport, HostileInputIsRefusedCleanly) {
  // Deep nesting, in the coordinates and in the properties: refused at the depth limit.
  const std::string deep = std::string(100000, '[') + std::string(100000, ']');
  EXPECT_EQ(geojson_error(R"({"type":"Polygon","coordinates":)" + deep + "}"),
            "in.geojson: nested deeper than 64 arrays and objects");
  std::string props;
  for (int i = 0; i < 100000; ++i) props += R"({"a":)";
  EXPECT_EQ(geojson_error(collection({feature("null", "", props)})),
            "in.geojson: nested deeper than 64 arrays and objects (in feature 0)");
  // 63 levels inside a feature are still read (and found wanting).
  EXPECT_NE(geojson_error(R"({"type":"Polygon","coordinates":)" + std::string(63, '[') +
                          std::string(63, ']') + "}")
                .find("feature 0: polygon 0, ring 0, point 0 holds something other"),
            std::string::npos);
  // A huge number is infinite, a long one still exact; a huge exponent underflows to 0.
  const std::string big = "1" + std::string(100000, '0');
  const std::string huge = geojson_error(R"({"type":"Point","coordinates":[)" + big + ",1]}");
  EXPECT_TRUE(huge.starts_with("in.geojson: not valid JSON: number overflow parsing '100000"))
      << huge;
  EXPECT_LT(huge.size(), 300u);
  const PointTable2 t =
      *import_geojson("in.geojson",
                      R"({"type":"Point","coordinates":[0.)" + big + "1,1e-99999999999999]}", {})
           .points;
  EXPECT_EQ(t.points[0], (Double2{0.1, 0}));
  // Truncated, binary and non-UTF-8 bytes: one line each.
  EXPECT_NE(geojson_error(R"({"type":"Point","coordinates":[1,)").find("not valid JSON"),
            std::string::npos);
  EXPECT_NE(geojson_error(std::string("{\"type\":\"\xff\"}")).find("not valid JSON"),
            std::string::npos);
  EXPECT_NE(geojson_error(std::string("\0\0\0", 3)).find("not valid JSON"), std::string::npos);
}

// The one number reader behind every CSV column (points, events, query inputs), against values
// written by hand and std::strtod.
TEST(CsvNumber, ParsesWhatTablesWrite) {
  const std::pair<const char*, double> good[] = {
      {"1", 1.0},        {" -2.5 ", -2.5}, {"\t+3e2\t", 300.0}, {"1e-400", 0.0},
      {"-1e-400", -0.0}, {"0.1", 0.1},     {"-87.904", -87.904}};
  for (const auto& [text, value] : good) {
    const auto parsed = parse_csv_number(text);
    ASSERT_TRUE(parsed) << text;
    EXPECT_EQ(*parsed, value) << text;
    EXPECT_EQ(std::signbit(*parsed), std::signbit(value)) << text;
  }
  EXPECT_EQ(*parse_csv_number("1e400"), std::numeric_limits<double>::infinity());
  EXPECT_EQ(*parse_csv_number("-1e400"), -std::numeric_limits<double>::infinity());
  EXPECT_EQ(*parse_csv_number("inf"), std::numeric_limits<double>::infinity());
  EXPECT_EQ(*parse_csv_number("+inf"), std::numeric_limits<double>::infinity());
  EXPECT_TRUE(std::isnan(*parse_csv_number("nan")));
  for (const char* bad : {"", " ", "+", "+-1", "1.2.3", "1,5", "0x10", "12abc", "--1", "e5"})
    EXPECT_FALSE(parse_csv_number(bad)) << bad;
  std::mt19937_64 rng(7);
  for (int i = 0; i < 1000; ++i) {
    const double v = std::uniform_real_distribution<double>(-1e6, 1e6)(rng);
    char text[64];
    std::snprintf(text, sizeof text, "%.17g", v);
    EXPECT_EQ(*parse_csv_number(text), std::strtod(text, nullptr)) << text;
  }
}

TEST(CsvPointImport, ReadsCoordinateColumns) {
  const std::string text =
      "\xEF\xBB\xBFzip,lat,lon,city\r\n"
      "00501,40.5,-72.25,\"Holtsville, NY\"\r\n"
      "\"00544\",\"41\",-72,\"a \"\"quoted\"\"\r\nname\"\r\n"
      "\r\n"
      "99999, +1.5 ,2e1,x";
  const PointTable2 t = import_csv_points("in.csv", text, csv_options("lon", "lat"));
  EXPECT_EQ(t.points, (std::vector<Double2>{{-72.25, 40.5}, {-72, 41}, {20, 1.5}}));
  EXPECT_TRUE(t.feature_points.empty());
  EXPECT_EQ(t.feature_count(), 3u);
  EXPECT_EQ(t.x_column, "lon");
  EXPECT_EQ(t.y_column, "lat");
  EXPECT_EQ(t.ids.size(), 0u);
  EXPECT_EQ(t.rows_skipped, 0u);
  EXPECT_EQ(t.bounds.min, (Double2{-72.25, 1.5}));
  EXPECT_EQ(t.bounds.max, (Double2{20, 41}));
}

TEST(CsvPointImport, ErrorsNameTheLine) {
  const GeoImportOptions o = csv_options("lon", "lat");
  EXPECT_EQ(csv_error("a,lat,lon\n1,2,3\n4,abc,5\n", o),
            "in.csv:3: column 'lat': 'abc' is not a number");
  EXPECT_EQ(csv_error("a,lat,lon\n\"multi\nline\",2,3\n4,5\n", o),
            "in.csv:4: column 'lon': missing (the row has 2 fields)");
  EXPECT_EQ(csv_error("a,lat,lon\r\n1,2,inf\r\n", o),
            "in.csv:2: column 'lon': 'inf' is not finite");
  EXPECT_EQ(csv_error("a,lat,lon\n1,2,1e400\n", o),
            "in.csv:2: column 'lon': '1e400' is not finite");
  EXPECT_EQ(csv_error("a,lat,lon\n1,,3\n", o), "in.csv:2: column 'lat': '' is not a number");
  EXPECT_EQ(csv_error("a,lat,lon\n1,0x10,3\n", o),
            "in.csv:2: column 'lat': '0x10' is not a number");
  EXPECT_EQ(csv_error("a,latitude,lon\n1,2,3\n", o),
            "in.csv:1: no column 'lat' in the header (columns: 'a', 'latitude', 'lon')");
  EXPECT_EQ(csv_error("a,lat,lon\n1,\"2\"x,3\n", o),
            "in.csv:2: text after the closing quote of a field");
  EXPECT_EQ(csv_error("a,lat,lon\n1,\"2,3\n", o), "in.csv:2: a quoted field never closes");
  EXPECT_EQ(csv_error("a,lat,lon\n", o), "in.csv: no rows after the header");
  EXPECT_EQ(csv_error("a,lat,lon\n1,2,3\n", {}),
            "in.csv: a CSV input needs --lon-column and --lat-column (or --x-column and "
            "--y-column) naming its coordinate columns");
}

TEST(CsvPointImport, SkipInvalidDropsRowsKeepingIndices) {
  const PointTable2 t =
      import_csv_points("in.csv", "x,y\n1,2\nbad,3\n4,5\n6\n7,8\n", csv_options("x", "y", true));
  EXPECT_EQ(t.rows_skipped, 2u);
  EXPECT_EQ(t.points, (std::vector<Double2>{{1, 2}, {4, 5}, {7, 8}}));
  EXPECT_EQ(t.feature_points, (std::vector<std::uint64_t>{0, 1, 1, 2, 2, 3}));
  EXPECT_EQ(t.feature_count(), 5u);
}

TEST(GeoImport, ZstInputsAndRouting) {
  test::TempDir dir;
  const std::string text = "lon,lat\n1,2\n3,4\n";
  std::vector<char> packed(ZSTD_compressBound(text.size()));
  packed.resize(ZSTD_compress(packed.data(), packed.size(), text.data(), text.size(), 3));
  test::write_file(dir.file("p.csv.zst"), std::as_bytes(std::span(packed)));
  const GeoInput in = import_geo_file(dir.file("p.csv.zst"), csv_options("lon", "lat"));
  ASSERT_TRUE(in.points);
  EXPECT_EQ(in.points->points, (std::vector<Double2>{{1, 2}, {3, 4}}));
  test::write_text(dir.file("bad.CSV"), "lon,lat\n1,x\n");
  EXPECT_EQ(error_of([&] { import_geo_file(dir.file("bad.CSV"), csv_options("lon", "lat")); }),
            dir.file("bad.CSV") + ":2: column 'lat': 'x' is not a number");
  test::write_text(dir.file("a.geojson"), R"({"type":"Point","coordinates":[1,2]})");
  EXPECT_TRUE(import_geo_file(dir.file("a.geojson"), {}).points);
  EXPECT_TRUE(is_geo_input_name("x.GeoJSON.zst"));
  EXPECT_TRUE(is_geo_input_name("x.json"));
  EXPECT_TRUE(is_csv_input_name("x.csv.ZST"));
  EXPECT_FALSE(is_geo_input_name("x.obj"));
  EXPECT_FALSE(is_geo_input_name("x.zst"));
}

TEST(GeoImport, SharedCountiesStatesCountries) {
  KILN_REQUIRE_GEO();
  // MANIFEST.md: 3,231 counties (3,121 Polygon, 110 MultiPolygon), 68,313 vertices counting
  // each ring's closing repeat; 3,531 rings, so 64,782 stored once. 22 rings have fewer than 3
  // distinct points (zero-area slivers of the 1:10M simplification) and are dropped.
  const GeoInput c = import_geo_file(geo_dir() + "/us-counties-10m.geojson.zst", {});
  ASSERT_TRUE(c.polygons);
  const PolygonLayer& counties = *c.polygons;
  EXPECT_EQ(counties.feature_count(), 3231u);
  EXPECT_EQ(c.degenerate_rings_dropped, 22u);
  EXPECT_EQ(c.null_geometries, 0u);
  EXPECT_EQ(counties.ring_count(), 3531u - 22u);
  EXPECT_EQ(counties.ids[0], "04015");
  EXPECT_EQ(counties.names[0], "Mohave");
  // Each dropped sliver held 4 positions.
  EXPECT_EQ(counties.vertices.size() + counties.ring_count(), 68313u - 22u * 4u);
  EXPECT_GT(counties.bounds.min.x, -180.0);
  EXPECT_LT(counties.bounds.max.y, 72.0);

  // States: Illinois (feature 19, id 17) has a ring that does not close.
  const std::string states = geo_dir() + "/us-states-10m.geojson.zst";
  EXPECT_EQ(error_of([&] { import_geo_file(states, {}); }),
            states +
                ": feature 19 (id 17): polygon 0, ring 0 is not closed: it starts at "
                "(-88.41357715247152, 37.42399851987519) and ends at (-88.41357715247152, "
                "37.42485757956579)");
  const PolygonLayer s = *import_geo_file(states, skipping()).polygons;
  EXPECT_EQ(s.feature_count(), 56u);
  EXPECT_EQ(s.features_skipped, 1u);

  const GeoInput w = import_geo_file(geo_dir() + "/countries-land-10km.geojson.zst", naming("A3"));
  ASSERT_TRUE(w.polygons);
  EXPECT_EQ(w.polygons->feature_count(), 220u);
  EXPECT_EQ(w.polygons->names[0], "CPV");
  EXPECT_EQ(w.polygons->ids[0], "");
  EXPECT_EQ(w.polygons->vertices.size() + w.polygons->ring_count(), 71129u);
}

TEST(GeoImport, SharedZipcodes) {
  KILN_REQUIRE_GEO();
  const GeoInput z =
      import_geo_file(geo_dir() + "/zipcodes.csv.zst", csv_options("longitude", "latitude"));
  ASSERT_TRUE(z.points);
  EXPECT_EQ(z.points->points.size(), 42049u);
  EXPECT_EQ(z.points->rows_skipped, 0u);
  EXPECT_EQ(z.points->points[0], (Double2{-72.637078, 40.922326}));
}

// `kiln build` end to end, with no structure (a map): the blob's layer is what the reader gave.
TEST(GeoImport, KilnBuildWritesTheLayer) {
  test::TempDir dir;
  const std::string text = collection({
      feature(std::string(R"({"type":"Polygon","coordinates":[)") + kSquare + "," + kHole + "]}",
              R"("a")", R"({"label":"first"})"),
      feature(R"({"type":"Polygon","coordinates":[[[0,0],[1,0],[1,1],[0,1]]]})", R"("b")"),
  });
  test::write_text(dir.file("m.geojson"), text);
  const std::string blob = dir.file("m.kiln");
  const auto build = [&](const std::string& flags) {
    return test::run_kiln("build " + test::quoted(dir.file("m.geojson")) + " -o " +
                          test::quoted(blob) + " " + flags);
  };
  test::CommandResult r = build("--name-property label");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "kiln build: " + dir.file("m.geojson") +
                       ": feature 1 (id b): polygon 0, ring 0 is not closed: it starts at (0, 0) "
                       "and ends at (0, 1)\n");
  r = build("--name-property label --skip-invalid");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "kiln build: warning: --skip-invalid dropped 1 feature; the first: " +
                       dir.file("m.geojson") +
                       ": feature 1 (id b): polygon 0, ring 0 is not closed: it starts at (0, 0) "
                       "and ends at (0, 1)\n");
  const Blob b = Blob::open_file(blob);
  b.verify();
  const PolygonLayerView layer = b.polygon_layer();
  const PolygonLayer given = *import_geojson("m.geojson", text,
                                             [] {
                                               GeoImportOptions o = naming("label");
                                               o.skip_invalid = true;
                                               return o;
                                             }())
                                  .polygons;
  EXPECT_EQ(layer.feature_count(), 2u);
  EXPECT_EQ(layer.features_skipped, 1u);
  EXPECT_EQ(layer.name_property, "label");
  EXPECT_EQ(layer.names[0], "first");
  EXPECT_EQ(layer.ids[1], "b");
  EXPECT_TRUE(std::equal(layer.vertices.begin(), layer.vertices.end(), given.vertices.begin(),
                         given.vertices.end()));
  EXPECT_TRUE(std::equal(layer.ring_vertices.begin(), layer.ring_vertices.end(),
                         given.ring_vertices.begin(), given.ring_vertices.end()));

  // A CSV needs its columns; a 2D input is alone; the flags are refused when they disagree.
  test::write_text(dir.file("p.csv"), "lon,lat\n1,2\n");
  r = test::run_kiln("build " + test::quoted(dir.file("p.csv")) + " -o " + test::quoted(blob));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "kiln build: " + dir.file("p.csv") +
                       ": a CSV input needs --lon-column and --lat-column (or --x-column and "
                       "--y-column) naming its coordinate columns\n");
  r = test::run_kiln("build " + test::quoted(dir.file("p.csv")) + " " +
                     test::quoted(dir.file("m.geojson")) + " -o " + test::quoted(blob));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "kiln build: " + dir.file("p.csv") +
                       ": a 2D input (GeoJSON, CSV) must be the blob's only input (2 inputs "
                       "given: build one blob each)\n");
  r = test::run_kiln("build " + test::quoted(dir.file("p.csv")) + " -o " + test::quoted(blob) +
                     " --lon-column lon --x-column lat --lat-column lat");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "kiln build: --lon-column and --x-column differ\n");
  r = test::run_kiln("build " + test::quoted(dir.file("m.geojson")) + " -o " + test::quoted(blob) +
                     " --lon-column lon");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err,
            "kiln build: --lon-column/--lat-column (--x-column/--y-column) apply to a CSV input "
            "only\n");
  r = test::run_kiln("build " + test::quoted(dir.file("p.csv")) + " -o " + test::quoted(blob) +
                     " --lon-column lon --lat-column lat");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Blob p = Blob::open_file(blob);
  EXPECT_EQ(p.point_table().x_column, "lon");
  EXPECT_EQ(p.point_table().points[0], (Double2{1, 2}));
}

// How a 2D input is read changes the blob, so it enters the build cache key.
TEST(GeoImport, ReadOptionsEnterTheCacheKey) {
  BuildOptions base;
  base.inputs = {"m.geojson"};
  const Hash128 hashes[1] = {};
  const Hash128 key = direct_key(base, hashes, "fp");
  for (int field = 0; field < 4; ++field) {
    BuildOptions other = base;
    if (field == 0) other.geo.name_property = "NAME";
    if (field == 1) other.geo.x_column = "lon";
    if (field == 2) other.geo.y_column = "lat";
    if (field == 3) other.geo.skip_invalid = true;
    EXPECT_NE(direct_key(other, hashes, "fp"), key) << field;
  }
}

}  // namespace
}  // namespace kiln
