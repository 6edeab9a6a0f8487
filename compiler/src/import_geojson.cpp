// GeoJSON (RFC 7946) into a PolygonLayer or a PointTable2, through nlohmann's SAX interface:
// its parser keeps its own stack (no recursion), and this handler refuses nesting deeper than
// kGeoJsonMaxDepth, so memory stays proportional to the input. A feature's coordinates are kept
// as a flat token list until the feature ends, since its "type" may come after them.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <system_error>
#include <vector>

#include "kiln/compiler/geo_import.hpp"

namespace kiln {
namespace {

using json = nlohmann::json;

// A feature-level problem: refused, or dropped with --skip-invalid.
struct FeatureError {
  std::string what;
};

// One feature's coordinates as read: '[' and ']' for arrays, 'n' a number (in `numbers`),
// 'x' anything else.
struct CoordTokens {
  std::vector<char> ops;
  std::vector<double> numbers;
  void clear() { ops.clear(), numbers.clear(); }
};

struct Geometry {
  bool present = false;  // a "geometry" (or top-level "coordinates") was seen, not null
  bool collection = false;
  std::string type;
  bool has_coordinates = false;
  CoordTokens coords;
};

struct FeatureState {
  std::string type, id, name, error;
  bool has_type = false;
  Geometry geometry;
  void clear() {
    type.clear(), id.clear(), name.clear(), error.clear();
    has_type = false;
    geometry.present = geometry.collection = geometry.has_coordinates = false;
    geometry.type.clear();
    geometry.coords.clear();
  }
};

// A number's text as a double, exactly (std::from_chars); out of range gives infinity, refused
// later as non-finite.
double parse_double(const std::string& raw) {
  double value = 0;
  const auto [end, ec] = std::from_chars(raw.data(), raw.data() + raw.size(), value);
  if (ec == std::errc::result_out_of_range) {
    // Underflow (a negative exponent) is zero, not an error; overflow is infinite.
    const std::size_t e = raw.find_first_of("eE");
    if (e != std::string::npos && e + 1 < raw.size() && raw[e + 1] == '-') return 0.0;
    return raw[0] == '-' ? -INFINITY : INFINITY;
  }
  if (ec != std::errc() || end != raw.data() + raw.size()) return NAN;  // never, for JSON
  return value;
}

// Text from the file for an error line: control characters as '?', at most 40 bytes, so the
// line stays one short line.
std::string printable(std::string_view text) {
  std::string out;
  for (std::size_t i = 0; i < text.size() && i < 40; ++i)
    out += static_cast<unsigned char>(text[i]) < 0x20 ? '?' : text[i];
  if (text.size() > 40) out += "...";
  return out;
}

// "(x, y)", each in the shortest text that reads back as the same double (as the file wrote it,
// usually).
std::string point_text(format::Double2 p) {
  char buffer[2][32];
  const auto x = std::to_chars(buffer[0], buffer[0] + 32, p.x).ptr;
  const auto y = std::to_chars(buffer[1], buffer[1] + 32, p.y).ptr;
  return "(" + std::string(buffer[0], x) + ", " + std::string(buffer[1], y) + ")";
}

// Reads the coordinate tokens of one geometry, appending to the layer or table being built.
class CoordReader {
 public:
  explicit CoordReader(const CoordTokens& t) : t_(t) {}

  bool at_end() const { return op_ == t_.ops.size(); }
  void open(const std::string& what) {
    if (op_ >= t_.ops.size() || t_.ops[op_] != '[') throw FeatureError{what + " is not an array"};
    ++op_;
  }
  // True (consumed) at the array's closing bracket.
  bool close() {
    if (op_ < t_.ops.size() && t_.ops[op_] == ']') return ++op_, true;
    return false;
  }
  // A position: [x, y, ...]; a third number (altitude) and more are ignored. Named in errors
  // "PREFIXpoint INDEX", or PREFIX alone without an index (built only on error: one per vertex
  // would cost more than the parse).
  format::Double2 position(const std::string& prefix, std::optional<std::size_t> index) {
    const auto name = [&] { return index ? prefix + "point " + std::to_string(*index) : prefix; };
    if (op_ >= t_.ops.size() || t_.ops[op_] != '[') throw FeatureError{name() + " is not an array"};
    ++op_;
    double xy[2] = {0, 0};
    std::size_t count = 0;
    while (!close()) {
      if (op_ >= t_.ops.size() || t_.ops[op_] != 'n')
        throw FeatureError{name() + " holds something other than numbers"};
      const double v = t_.numbers[num_++];
      if (count < 2) xy[count] = v;
      ++count, ++op_;
    }
    if (count < 2)
      throw FeatureError{name() + " has " + std::to_string(count) + " coordinates, not 2"};
    if (!std::isfinite(xy[0]) || !std::isfinite(xy[1]))
      throw FeatureError{name() + " has a coordinate that is not finite"};
    return {xy[0], xy[1]};
  }

 private:
  const CoordTokens& t_;
  std::size_t op_ = 0, num_ = 0;
};

// Whether the ring's points (closing repeat dropped) hold at least 3 distinct points.
bool has_three_distinct(std::span<const format::Double2> ring) {
  const format::Double2 a = ring[0];
  std::size_t i = 1;
  while (i < ring.size() && ring[i] == a) ++i;
  if (i == ring.size()) return false;
  const format::Double2 b = ring[i];
  for (; i < ring.size(); ++i)
    if (ring[i] != a && ring[i] != b) return true;
  return false;
}

class LayerBuilder {
 public:
  LayerBuilder(std::string path, const GeoImportOptions& options)
      : path_(std::move(path)), options_(options) {
    table_.feature_points = {0};  // until finish() finds one point per feature
  }

  void add_feature(const FeatureState& f, std::size_t index, bool in_collection);
  GeoInput finish();

 private:
  enum class Kind { kNone, kPolygons, kPoints };
  std::string where(std::size_t index, const std::string& id) const {
    return path_ + ": feature " + std::to_string(index) +
           (id.empty() ? "" : " (id " + printable(id) + ")") + ": ";
  }
  void check_kind(Kind kind, const std::string& type, std::size_t index, const std::string& id);
  void read_polygons(const Geometry& g);
  void read_polygon(CoordReader& r, const std::string& what);
  void read_points(const Geometry& g);
  void close_feature() {
    layer_.feature_polygons.push_back(layer_.polygon_count());
    table_.feature_points.push_back(table_.points.size());
  }
  void rollback();

  std::string path_;
  const GeoImportOptions& options_;
  Kind kind_ = Kind::kNone;
  std::size_t kind_feature_ = 0;
  std::string kind_type_;
  PolygonLayer layer_;
  PointTable2 table_;
  StringColumn ids_, names_;
  std::uint64_t null_geometries_ = 0, degenerate_ = 0, feature_degenerate_ = 0, skipped_ = 0;
  std::string first_skipped_;
};

void LayerBuilder::check_kind(Kind kind, const std::string& type, std::size_t index,
                              const std::string& id) {
  if (kind_ == Kind::kNone) {
    kind_ = kind, kind_feature_ = index, kind_type_ = type;
    return;
  }
  if (kind_ != kind)
    throw ImportError(where(index, id) + "a " + type + " in a layer of " +
                      (kind_ == Kind::kPolygons ? "polygons" : "points") + " (feature " +
                      std::to_string(kind_feature_) + " is a " + kind_type_ +
                      "): a layer holds polygons or points, not both");
}

void LayerBuilder::read_polygon(CoordReader& r, const std::string& what) {
  r.open(what);
  bool dropped = false;  // a degenerate outer ring drops the polygon with its holes
  std::size_t ring = 0;
  for (; !r.close(); ++ring) {
    const std::string ring_what = what + ", ring " + std::to_string(ring);
    r.open(ring_what);
    const std::size_t begin = layer_.vertices.size();
    const std::string prefix = ring_what + ", ";
    for (std::size_t i = 0; !r.close(); ++i) layer_.vertices.push_back(r.position(prefix, i));
    const std::span<const format::Double2> v(layer_.vertices.data() + begin,
                                             layer_.vertices.size() - begin);
    if (v.size() < 4)
      throw FeatureError{ring_what + " has " + std::to_string(v.size()) +
                         " points; a closed ring needs at least 4 (the first repeated last)"};
    if (v.front() != v.back())
      throw FeatureError{ring_what + " is not closed: it starts at " + point_text(v.front()) +
                         " and ends at " + point_text(v.back())};
    layer_.vertices.pop_back();  // stored once
    if (dropped || !has_three_distinct(v.first(v.size() - 1))) {
      if (!dropped) ++feature_degenerate_;
      if (ring == 0) dropped = true;
      layer_.vertices.resize(begin);
      continue;
    }
    layer_.ring_vertices.push_back(layer_.vertices.size());
  }
  if (ring == 0) throw FeatureError{what + " has no ring"};
  if (!dropped) layer_.polygon_rings.push_back(layer_.ring_count());
}

void LayerBuilder::read_polygons(const Geometry& g) {
  CoordReader r(g.coords);
  if (g.type == "Polygon") {
    // A Polygon's coordinates are its rings: read them as polygon 0.
    read_polygon(r, "polygon 0");
  } else {
    r.open("the coordinates");
    for (std::size_t p = 0; !r.close(); ++p) read_polygon(r, "polygon " + std::to_string(p));
  }
  if (!r.at_end()) throw FeatureError{"the coordinates hold more than one array"};
}

void LayerBuilder::read_points(const Geometry& g) {
  CoordReader r(g.coords);
  if (g.type == "Point") {
    table_.points.push_back(r.position("the point", std::nullopt));
  } else {
    r.open("the coordinates");
    for (std::size_t i = 0; !r.close(); ++i) table_.points.push_back(r.position("", i));
  }
  if (!r.at_end()) throw FeatureError{"the coordinates hold more than one array"};
}

void LayerBuilder::rollback() {
  // Back to the state before the feature: its vertices, rings, polygons and points.
  layer_.polygon_rings.resize(layer_.feature_polygons.back() + 1);
  layer_.ring_vertices.resize(layer_.polygon_rings.back() + 1);
  layer_.vertices.resize(layer_.ring_vertices.back());
  table_.points.resize(table_.feature_points.back());
}

void LayerBuilder::add_feature(const FeatureState& f, std::size_t index, bool in_collection) {
  feature_degenerate_ = 0;
  try {
    if (!f.error.empty()) throw FeatureError{f.error};
    if (in_collection && !f.has_type) throw FeatureError{"has no \"type\""};
    if (in_collection && f.type != "Feature")
      throw FeatureError{"its type is '" + printable(f.type) + "', not 'Feature'"};
    const Geometry& g = f.geometry;
    if (g.collection || g.type == "GeometryCollection")
      throw FeatureError{
          "a GeometryCollection is not supported (only Polygon, MultiPolygon, "
          "Point, MultiPoint)"};
    if (!g.present) {
      ++null_geometries_;
    } else if (g.type == "Polygon" || g.type == "MultiPolygon") {
      check_kind(Kind::kPolygons, g.type, index, f.id);
      if (!g.has_coordinates) throw FeatureError{"the " + g.type + " has no \"coordinates\""};
      read_polygons(g);
    } else if (g.type == "Point" || g.type == "MultiPoint") {
      check_kind(Kind::kPoints, g.type, index, f.id);
      if (!g.has_coordinates) throw FeatureError{"the " + g.type + " has no \"coordinates\""};
      read_points(g);
    } else if (g.type.empty()) {
      throw FeatureError{"its geometry has no \"type\""};
    } else {
      throw FeatureError{"a geometry of type '" + printable(g.type) +
                         "' is not supported (only Polygon, MultiPolygon, Point, MultiPoint)"};
    }
    degenerate_ += feature_degenerate_;
  } catch (const FeatureError& e) {
    if (!options_.skip_invalid) throw ImportError(where(index, f.id) + e.what);
    rollback();
    if (skipped_++ == 0) first_skipped_ = where(index, f.id) + e.what;
  }
  ids_.push(f.id);
  names_.push(f.name);
  close_feature();
}

GeoInput LayerBuilder::finish() {
  GeoInput out;
  out.null_geometries = null_geometries_;
  out.degenerate_rings_dropped = degenerate_;
  if (kind_ == Kind::kNone)
    throw ImportError(path_ + ": no Polygon, MultiPolygon, Point or MultiPoint geometry in " +
                      std::to_string(ids_.size()) + " features");
  if (kind_ == Kind::kPolygons) {
    layer_.ids = std::move(ids_), layer_.names = std::move(names_);
    layer_.name_property = options_.name_property;
    layer_.features_skipped = skipped_;
    layer_.first_skipped = first_skipped_;
    for (const format::Double2& v : layer_.vertices) layer_.bounds.grow(v);
    out.polygons = std::move(layer_);
  } else {
    table_.ids = std::move(ids_), table_.names = std::move(names_);
    table_.name_property = options_.name_property;
    table_.rows_skipped = skipped_;
    table_.first_skipped = first_skipped_;
    for (const format::Double2& p : table_.points) table_.bounds.grow(p);
    // Point i is feature i when every feature holds exactly one point: no offsets needed.
    bool one_each = table_.feature_points.size() == table_.points.size() + 1;
    for (std::size_t i = 0; one_each && i < table_.points.size(); ++i)
      one_each = table_.feature_points[i + 1] == i + 1;
    if (one_each) table_.feature_points.clear();
    out.points = std::move(table_);
  }
  return out;
}

// Where the parser is: each open array or object has a role.
enum class Role : std::uint8_t {
  kTop,         // the top-level object: a collection, a feature or a geometry
  kFeatures,    // the "features" array
  kFeature,     // a feature object
  kGeometry,    // a geometry object
  kCoords,      // inside "coordinates" (any depth)
  kProperties,  // a feature's "properties"
  kIgnored,     // anything else, skipped
};

class GeoJsonHandler : public nlohmann::json_sax<json> {
 public:
  GeoJsonHandler(const std::string& path, std::string_view text, const GeoImportOptions& options)
      : path_(path), text_(text), options_(options), builder_(path, options) {}

  bool null() override { return scalar(Scalar::kNull, {}); }
  bool boolean(bool v) override { return scalar(Scalar::kOther, v ? "true" : "false"); }
  bool number_integer(number_integer_t v) override { return number(double(v), std::to_string(v)); }
  bool number_unsigned(number_unsigned_t v) override {
    return number(double(v), std::to_string(v));
  }
  bool number_float(number_float_t, const string_t& raw) override {
    return number(parse_double(raw), raw);
  }
  bool string(string_t& v) override { return scalar(Scalar::kString, v); }
  bool binary(binary_t&) override { return scalar(Scalar::kOther, {}); }
  bool start_object(std::size_t) override { return open(false); }
  bool end_object() override { return close(); }
  bool start_array(std::size_t) override { return open(true); }
  bool end_array() override { return close(); }
  bool key(string_t& k) override {
    stack_.back().key = k;
    return true;
  }
  bool parse_error(std::size_t position, const std::string&,
                   const nlohmann::detail::exception& e) override;

  GeoInput finish();
  const std::string& fatal() const { return fatal_; }

 private:
  enum class Scalar { kNull, kString, kNumber, kOther };
  struct Frame {
    Role role;
    bool array;
    std::string key;  // the key whose value is being read (objects)
  };

  FeatureState& feature() { return in_collection_ ? current_ : top_; }
  bool open(bool array);
  bool close();
  bool scalar(Scalar kind, std::string_view text);
  bool number(double value, const std::string& text) {
    if (!stack_.empty() && stack_.back().role == Role::kCoords) {
      current_geometry().coords.ops.push_back('n');
      current_geometry().coords.numbers.push_back(value);
      return true;
    }
    return scalar(Scalar::kNumber, text);
  }
  Geometry& current_geometry() { return feature().geometry; }
  Role child_role(const Frame& parent, bool array);
  void feature_scalar(FeatureState& f, const std::string& key, Scalar kind, std::string_view text);
  bool fail(std::string what) {
    fatal_ = std::move(what);
    return false;
  }

  const std::string& path_;
  std::string_view text_;
  const GeoImportOptions& options_;
  LayerBuilder builder_;
  std::vector<Frame> stack_;
  FeatureState top_, current_;
  std::string top_type_;
  bool in_collection_ = false, has_features_ = false;
  std::size_t feature_index_ = 0;
  std::string fatal_;
};

bool GeoJsonHandler::parse_error(std::size_t position, const std::string&,
                                 const nlohmann::detail::exception& e) {
  std::string what = e.what();
  // "[json.exception.parse_error.101] parse error at line 1, column 2: ..." -> after "] ".
  if (const auto bracket = what.find("] "); bracket != std::string::npos)
    what = what.substr(bracket + 2);
  // The token quoted may be a whole (huge) number: keep the line short.
  if (what.size() > 200) what = what.substr(0, 200) + "...";
  if (what.find(" at line ") == std::string::npos) {
    // An out-of-range number: say where.
    const std::size_t end = std::min(position, text_.size());
    const auto line = std::count(text_.begin(), text_.begin() + std::ptrdiff_t(end), '\n') + 1;
    what += " at line " + std::to_string(line);
  }
  if (in_collection_) what += " (in feature " + std::to_string(feature_index_) + ")";
  fatal_ = path_ + ": not valid JSON: " + what;
  return false;
}

Role GeoJsonHandler::child_role(const Frame& parent, bool array) {
  const std::string& k = parent.key;
  switch (parent.role) {
    case Role::kTop:
      if (k == "features" && array) return Role::kFeatures;
      if (k == "geometry" && !array) return Role::kGeometry;
      if (k == "properties" && !array) return Role::kProperties;
      if (k == "coordinates" && array) return Role::kCoords;
      return Role::kIgnored;
    case Role::kFeatures:
      return Role::kFeature;
    case Role::kFeature:
      if (k == "geometry" && !array) return Role::kGeometry;
      if (k == "properties" && !array) return Role::kProperties;
      return Role::kIgnored;
    case Role::kGeometry:
      return k == "coordinates" && array ? Role::kCoords : Role::kIgnored;
    case Role::kCoords:
      return Role::kCoords;
    default:
      return Role::kIgnored;
  }
}

bool GeoJsonHandler::open(bool array) {
  if (stack_.size() >= kGeoJsonMaxDepth)
    return fail(path_ + ": nested deeper than " + std::to_string(kGeoJsonMaxDepth) +
                " arrays and objects" +
                (in_collection_ ? " (in feature " + std::to_string(feature_index_) + ")" : ""));
  Role role = Role::kTop;
  if (stack_.empty()) {
    if (array) return fail(path_ + ": not GeoJSON: the top level is an array, not an object");
  } else {
    role = child_role(stack_.back(), array);
    Frame& parent = stack_.back();
    if (role == Role::kFeature) {
      in_collection_ = true;
      current_.clear();
      if (array) current_.error = "is an array, not an object";
    } else if (role == Role::kFeatures) {
      has_features_ = true;
    } else if (role == Role::kGeometry) {
      current_geometry().present = true;
    } else if (role == Role::kCoords) {
      if (parent.role != Role::kCoords) {
        current_geometry().has_coordinates = true;
        current_geometry().coords.clear();
      }
      current_geometry().coords.ops.push_back('[');
    } else if (parent.role == Role::kProperties && parent.key == options_.name_property) {
      feature().error = "its property '" + printable(options_.name_property) + "' is an " +
                        (array ? "array" : "object") + ", not a string or number";
    } else if ((parent.role == Role::kFeature || parent.role == Role::kTop) && parent.key == "id") {
      feature().error = "its id is not a string or number";
    }
  }
  stack_.push_back({role, array, {}});
  return true;
}

bool GeoJsonHandler::close() {
  const Frame frame = std::move(stack_.back());
  stack_.pop_back();
  if (frame.role == Role::kCoords) current_geometry().coords.ops.push_back(']');
  if (frame.role == Role::kFeature) {
    builder_.add_feature(current_, feature_index_++, true);
  }
  if (!stack_.empty()) stack_.back().key.clear();
  return true;
}

void GeoJsonHandler::feature_scalar(FeatureState& f, const std::string& key, Scalar kind,
                                    std::string_view text) {
  if (key == "id") {
    if (kind == Scalar::kString || kind == Scalar::kNumber)
      f.id = text;
    else if (kind != Scalar::kNull)
      f.error = "its id is not a string or number";
  } else if (key == "type" && kind == Scalar::kString) {
    f.type = text, f.has_type = true;
  } else if (key == "geometry" && kind != Scalar::kNull) {
    f.error = "its geometry is not an object or null";
  }
}

bool GeoJsonHandler::scalar(Scalar kind, std::string_view text) {
  if (stack_.empty()) return fail(path_ + ": not GeoJSON: the top level is not an object");
  Frame& frame = stack_.back();
  switch (frame.role) {
    case Role::kTop:
      if (frame.key == "type" && kind == Scalar::kString) top_type_ = text;
      if (frame.key == "coordinates") top_.error = "its coordinates are not an array";
      feature_scalar(top_, frame.key, kind, text);
      break;
    case Role::kFeatures: {
      // A feature that is not an object: one broken feature.
      current_.clear();
      current_.error = "is not an object";
      builder_.add_feature(current_, feature_index_++, true);
      break;
    }
    case Role::kFeature:
      feature_scalar(current_, frame.key, kind, text);
      break;
    case Role::kGeometry:
      if (frame.key == "type" && kind == Scalar::kString) current_geometry().type = text;
      if (frame.key == "coordinates") feature().error = "its coordinates are not an array";
      if (frame.key == "geometries") current_geometry().collection = true;
      break;
    case Role::kCoords:
      current_geometry().coords.ops.push_back('x');
      break;
    case Role::kProperties:
      if (frame.key == options_.name_property) {
        if (kind == Scalar::kString || kind == Scalar::kNumber || kind == Scalar::kOther)
          feature().name = text;
        else
          feature().name.clear();
      }
      break;
    case Role::kIgnored:
      break;
  }
  frame.key.clear();
  return true;
}

GeoInput GeoJsonHandler::finish() {
  if (has_features_) {
    if (top_type_ != "FeatureCollection")
      throw ImportError(path_ + ": not GeoJSON: an object with \"features\" whose type is '" +
                        printable(top_type_) + "', not 'FeatureCollection'");
  } else if (top_type_ == "Feature") {
    builder_.add_feature(top_, 0, false);
  } else if (top_type_ == "FeatureCollection") {
    throw ImportError(path_ + ": not GeoJSON: a FeatureCollection with no \"features\" array");
  } else if (top_type_.empty()) {
    throw ImportError(path_ + ": not GeoJSON: the top-level object has no \"type\"");
  } else {
    // A bare geometry: one feature with no id or name.
    FeatureState f;
    f.error = top_.error;
    f.geometry = std::move(top_.geometry);
    f.geometry.present = true;
    f.geometry.type = top_type_;
    builder_.add_feature(f, 0, false);
  }
  return builder_.finish();
}

}  // namespace

GeoInput import_geojson(const std::string& path, std::string_view text,
                        const GeoImportOptions& options) {
  GeoJsonHandler handler(path, text, options);
  bool ok = false;
  try {
    ok = json::sax_parse(text.begin(), text.end(), &handler, json::input_format_t::json, true);
  } catch (const std::bad_alloc&) {
    throw ImportError(path + ": out of memory while reading");
  }
  if (!ok) throw ImportError(handler.fatal().empty() ? path + ": not valid JSON" : handler.fatal());
  return handler.finish();
}

}  // namespace kiln
