// Kiln's PLY reader. Assimp 5.2.5 reads a `tristrips` element as one triangle, so Kiln reads PLY
// itself, keeping what the Assimp path produced for everything else:
// - Header: `format ascii|binary_little_endian|binary_big_endian 1.0`, `element`, `property`
//   (scalar or `list`), `comment` and `obj_info`; other lines are skipped, as Assimp did (Blender
//   2.47 writes one without `comment`). Types: char/int8 ... double/float64.
// - `vertex`: x, y, z of any numeric type; normals when nx, ny and nz are all present; colours
//   when red/green/blue (or r/g/b) are (integers scaled by their type's maximum, floats as they
//   are, missing channels 0, alpha 1). Other properties are read and ignored.
// - `face`: a `vertex_indices` (or `vertex_index`) list of any integer type, fanned into n - 2
//   triangles (i0, ik, ik+1); faces of one or two vertices carry no surface.
// - `tristrips`: the same list, -1 restarting the strip; triangle i of a run is (a, b, c) for
//   even i and (b, a, c) for odd i; those naming a vertex twice (the strip's joints) are left out.
// - ASCII entries are one per line (extra values on a line are ignored), reals parsed as Assimp
//   parsed them; other elements are skipped. No faces and no strips: a point cloud.
// - Used vertices at the same position whose normals and texture coordinates are within 1e-5
//   (and whose colours are equal) are joined, as Assimp's JoinIdenticalVertices did.
// Counts are bounded by the bytes that could hold them before anything is allocated.
#include "import_ply.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <span>
#include <stdexcept>
#include <string_view>
#include <type_traits>
#include <utility>

#include "join_vertices.hpp"
#include "kiln/compiler/import.hpp"
#include "parse_real.hpp"
#include "rgba8.hpp"

namespace kiln {

namespace {

// A fault inside an element's data; read_elements adds the file, element, entry and place.
class Malformed : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class Type : std::uint8_t { int8, uint8, int16, uint16, int32, uint32, float32, float64 };

struct TypeInfo {
  std::string_view names[2];
  Type type;
  std::size_t size;
  double min, max;  // integers only
};

constexpr TypeInfo kTypes[] = {
    {{"char", "int8"}, Type::int8, 1, -128, 127},
    {{"uchar", "uint8"}, Type::uint8, 1, 0, 255},
    {{"short", "int16"}, Type::int16, 2, -32768, 32767},
    {{"ushort", "uint16"}, Type::uint16, 2, 0, 65535},
    {{"int", "int32"}, Type::int32, 4, -2147483648.0, 2147483647.0},
    {{"uint", "uint32"}, Type::uint32, 4, 0, 4294967295.0},
    {{"float", "float32"}, Type::float32, 4, 0, 0},
    {{"double", "float64"}, Type::float64, 8, 0, 0},
};

const TypeInfo& info(Type type) {
  return kTypes[std::size_t(type)];
}
bool is_integer(Type type) {
  return type != Type::float32 && type != Type::float64;
}

std::optional<Type> parse_type(std::string_view name) {
  for (const TypeInfo& t : kTypes)
    if (name == t.names[0] || name == t.names[1]) return t.type;
  return std::nullopt;
}

// At most 32 characters of `text`, control and non-ASCII bytes as '?': safe for a one-line error.
std::string printable(std::string_view text) {
  std::string out(text.substr(0, 32));
  for (char& c : out)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) > 0x7E) c = '?';
  return text.size() > 32 ? out + "..." : out;
}

// ---------------------------------------------------------------------------------------------
// Header

struct Property {
  std::string name;
  Type type = Type::float32;       // of the value, or of a list's items
  std::optional<Type> count_type;  // set for a list
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> properties;
};

enum class Encoding { ascii, little_endian, big_endian };

struct Header {
  Encoding encoding = Encoding::ascii;
  std::vector<Element> elements;
  std::size_t body_offset = 0;  // first byte after end_header's line
  std::size_t body_line = 0;    // line number of that byte (ASCII errors)
};

std::vector<std::string_view> split_words(std::string_view line) {
  std::vector<std::string_view> words;
  std::size_t at = 0;
  while (true) {
    at = line.find_first_not_of(" \t\r\v\f", at);
    if (at == std::string_view::npos) return words;
    const std::size_t end = std::min(line.find_first_of(" \t\r\v\f", at), line.size());
    words.push_back(line.substr(at, end - at));
    at = end;
  }
}

Encoding parse_format(const std::vector<std::string_view>& words) {
  if (words.size() != 3 || words[2] != "1.0")
    throw Malformed("expected 'format ascii|binary_little_endian|binary_big_endian 1.0'");
  if (words[1] == "ascii") return Encoding::ascii;
  if (words[1] == "binary_little_endian") return Encoding::little_endian;
  if (words[1] == "binary_big_endian") return Encoding::big_endian;
  throw Malformed("unknown format '" + printable(words[1]) + "'");
}

Element parse_element(const std::vector<std::string_view>& words) {
  Element element;
  if (words.size() != 3) throw Malformed("expected 'element NAME COUNT'");
  element.name = std::string(words[1]);
  const auto [end, ec] =
      std::from_chars(words[2].data(), words[2].data() + words[2].size(), element.count);
  if (ec != std::errc() || end != words[2].data() + words[2].size())
    throw Malformed("element count '" + printable(words[2]) + "' is not a number");
  return element;
}

Property parse_property(const std::vector<std::string_view>& words) {
  const bool list = words.size() >= 2 && words[1] == "list";
  if (words.size() != (list ? 5u : 3u))
    throw Malformed("expected 'property TYPE NAME' or 'property list COUNT_TYPE TYPE NAME'");
  Property property;
  property.name = std::string(words.back());
  const auto type = parse_type(words[words.size() - 2]);
  if (!type) throw Malformed("unknown type '" + printable(words[words.size() - 2]) + "'");
  property.type = *type;
  if (list) {
    property.count_type = parse_type(words[2]);
    if (!property.count_type || !is_integer(*property.count_type))
      throw Malformed("list count type '" + printable(words[2]) + "' is not an integer type");
  }
  return property;
}

// Applies one header line to `header`; returns false at end_header.
bool parse_header_line(std::string_view line, Header& header, bool& has_format) {
  const auto words = split_words(line);
  if (words.empty() || words[0] == "comment" || words[0] == "obj_info") return true;
  if (words[0] == "end_header") return false;
  if (words[0] == "format") {
    header.encoding = parse_format(words);
    has_format = true;
  } else if (words[0] == "element") {
    header.elements.push_back(parse_element(words));
  } else if (words[0] == "property") {
    if (header.elements.empty()) throw Malformed("property before any element");
    header.elements.back().properties.push_back(parse_property(words));
  }
  return true;  // an unknown line is skipped
}

Header parse_header(const std::string& path, std::span<const std::byte> bytes) {
  const std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  Header header;
  bool has_format = false;
  std::size_t at = 0, line_number = 0;
  while (at < text.size()) {
    const std::size_t end = std::min(text.find('\n', at), text.size());
    const std::string_view line = text.substr(at, end - at);
    at = end + 1;
    line_number += 1;
    if (line_number == 1) {
      const auto words = split_words(line);
      if (words.size() != 1 || words[0] != "ply")
        throw ImportError(path + ": not a PLY file (the first line is not 'ply')");
      continue;
    }
    try {
      if (parse_header_line(line, header, has_format)) continue;
    } catch (const Malformed& e) {
      throw ImportError(path + ": header line " + std::to_string(line_number) + ": " + e.what());
    }
    if (!has_format) throw ImportError(path + ": the header has no 'format' line");
    header.body_offset = std::min(at, text.size());
    header.body_line = line_number + 1;
    return header;
  }
  throw ImportError(path + ": the header has no 'end_header' line");
}

// ---------------------------------------------------------------------------------------------
// Bodies: values one at a time, as doubles (every PLY type converts exactly).

class BinaryBody {
 public:
  BinaryBody(std::span<const std::byte> bytes, bool big_endian)
      : bytes_(bytes), swap_(big_endian != (std::endian::native == std::endian::big)) {}
  std::uint64_t bytes_left() const { return bytes_.size() - at_; }
  std::uint64_t values_left(Type type) const { return bytes_left() / info(type).size; }
  std::string where() const { return " (byte " + std::to_string(entry_start_) + " of the body)"; }
  void start_entry() { entry_start_ = at_; }
  void skip(Type type, std::uint64_t count) { at_ += count * info(type).size; }  // count checked

  double next(Type type) {
    const std::size_t size = info(type).size;
    if (size > bytes_left()) throw Malformed("the file ends inside this entry");
    std::array<unsigned char, 8> raw{};
    std::memcpy(raw.data(), bytes_.data() + at_, size);
    at_ += size;
    if (swap_) std::reverse(raw.begin(), raw.begin() + std::ptrdiff_t(size));
    return decode(type, raw.data());
  }

 private:
  template <class T>
  static double load(const unsigned char* raw) {
    T value;
    std::memcpy(&value, raw, sizeof value);
    return double(value);
  }
  static double decode(Type type, const unsigned char* raw) {
    switch (type) {
      case Type::int8:
        return load<std::int8_t>(raw);
      case Type::uint8:
        return load<std::uint8_t>(raw);
      case Type::int16:
        return load<std::int16_t>(raw);
      case Type::uint16:
        return load<std::uint16_t>(raw);
      case Type::int32:
        return load<std::int32_t>(raw);
      case Type::uint32:
        return load<std::uint32_t>(raw);
      case Type::float32:
        return load<float>(raw);
      case Type::float64:
        return load<double>(raw);
    }
    return 0;
  }

  std::span<const std::byte> bytes_;
  bool swap_;
  std::size_t at_ = 0, entry_start_ = 0;
};

// A token as a value of `type`: integers must be integers in the type's range.
double parse_number(std::string_view token, Type type) {
  std::optional<double> value;
  if (type == Type::float32) {
    value = parse_real<float>(token);
  } else if (type == Type::float64) {
    value = parse_real<double>(token);
  } else {
    const std::string_view digits = token.size() > 1 && token[0] == '+' ? token.substr(1) : token;
    std::int64_t integer = 0;
    const auto got = std::from_chars(digits.data(), digits.data() + digits.size(), integer);
    if (got.ec == std::errc() && got.ptr == digits.data() + digits.size() &&
        double(integer) >= info(type).min && double(integer) <= info(type).max)
      value = double(integer);
  }
  if (!value)
    throw Malformed("'" + printable(token) + "' is not a valid " +
                    std::string(info(type).names[0]));
  return *value;
}

class AsciiBody {
 public:
  AsciiBody(std::span<const std::byte> bytes, std::size_t first_line)
      : text_(reinterpret_cast<const char*>(bytes.data()), bytes.size()), next_line_(first_line) {}
  std::uint64_t bytes_left() const { return text_.size() - at_; }
  // Each value needs a character and a separator (the last one's may be the line's end).
  std::uint64_t values_left(Type) const { return (line_.size() + 1) / 2; }
  std::string where() const { return " (line " + std::to_string(line_number_) + ")"; }

  // Moves to the entry's line, the next one that is not blank.
  void start_entry() {
    do {
      if (at_ >= text_.size()) {
        line_number_ = next_line_;
        throw Malformed("the file ends before this entry");
      }
      const std::size_t end = std::min(text_.find('\n', at_), text_.size());
      line_ = text_.substr(at_, end - at_);
      at_ = end + 1;
      line_number_ = next_line_++;
    } while (line_.find_first_not_of(" \t\r\v\f") == std::string_view::npos);
  }

  double next(Type type) {
    const std::size_t start = line_.find_first_not_of(" \t\r\v\f");
    if (start == std::string_view::npos) throw Malformed("the line has too few values");
    const std::size_t end = std::min(line_.find_first_of(" \t\r\v\f", start), line_.size());
    const std::string_view token = line_.substr(start, end - start);
    line_.remove_prefix(end);
    return parse_number(token, type);
  }
  void skip(Type type, std::uint64_t count) {
    for (std::uint64_t i = 0; i < count; ++i) next(type);
  }

 private:
  std::string_view text_, line_;
  std::size_t at_ = 0, next_line_, line_number_ = 0;
};

// ---------------------------------------------------------------------------------------------
// Elements

struct PlyData {
  ImportedMesh mesh;
  std::vector<std::array<float, 2>> uvs;  // only to join vertices as Assimp did
  bool has_vertices = false;
  bool has_edges = false;  // a face or strip of two or more vertices: a surface, not a cloud
};

// Refuses an element whose entries cannot all fit in the bytes left, before any allocation.
template <class Body>
void check_fits(const Element& element, const Body& body, bool ascii) {
  if (element.count == 0) return;
  if (element.properties.empty()) throw Malformed("has entries but no properties");
  std::uint64_t least = 0;  // bytes per entry, lists empty; in ASCII, a value and a separator
  for (const Property& p : element.properties)
    least += ascii ? 2 : info(p.count_type.value_or(p.type)).size;
  const std::uint64_t room = body.bytes_left() + (ascii ? 1 : 0);  // the last line's end optional
  if (element.count > room / least)
    throw Malformed("claims " + std::to_string(element.count) + " entries, more than the " +
                    std::to_string(body.bytes_left()) + " bytes left can hold");
}

// A list's length, checked against what is left to hold its items.
template <class Body>
std::uint64_t list_length(Body& body, const Property& property) {
  const double count = body.next(*property.count_type);
  if (count < 0) throw Malformed("a list has a negative length");
  if (count > double(body.values_left(property.type)))
    throw Malformed("a list of " + std::to_string(std::uint64_t(count)) +
                    " items runs past the end of the " +
                    (std::is_same_v<Body, AsciiBody> ? "line" : "file"));
  return std::uint64_t(count);
}

// Reads one entry: scalars into `values` (by property index), the list at `list_index` into
// `list` (integers), every other list skipped.
template <class Body>
void read_entry(const Element& element, Body& body, std::span<double> values,
                std::size_t list_index, std::vector<std::int64_t>& list) {
  body.start_entry();
  for (std::size_t p = 0; p < element.properties.size(); ++p) {
    const Property& property = element.properties[p];
    if (!property.count_type) {
      values[p] = body.next(property.type);
      continue;
    }
    const std::uint64_t length = list_length(body, property);
    if (p != list_index) {
      body.skip(property.type, length);
      continue;
    }
    list.resize(length);
    for (auto& item : list) item = std::int64_t(body.next(property.type));
  }
}

enum Role : std::uint8_t { kX, kY, kZ, kNx, kNy, kNz, kRed, kGreen, kBlue, kAlpha, kU, kV, kRoles };

std::optional<Role> role_of(std::string_view name) {
  static constexpr std::pair<std::string_view, Role> kNames[] = {
      {"x", kX},        {"y", kY},         {"z", kZ},         {"nx", kNx},       {"ny", kNy},
      {"nz", kNz},      {"red", kRed},     {"r", kRed},       {"green", kGreen}, {"g", kGreen},
      {"blue", kBlue},  {"b", kBlue},      {"alpha", kAlpha}, {"u", kU},         {"s", kU},
      {"tx", kU},       {"texture_u", kU}, {"v", kV},         {"t", kV},         {"ty", kV},
      {"texture_v", kV}};
  for (const auto& [known, role] : kNames)
    if (name == known) return role;
  return std::nullopt;
}

// Which property (index) plays each role in the vertex element; -1 where none does.
struct VertexLayout {
  std::array<int, kRoles> property;
  bool has(Role role) const { return property[role] >= 0; }
  bool normals() const { return has(kNx) && has(kNy) && has(kNz); }
  bool colors() const { return has(kRed) || has(kGreen) || has(kBlue); }
  bool uvs() const { return has(kU) || has(kV); }
};

VertexLayout vertex_layout(const Element& element) {
  VertexLayout layout;
  layout.property.fill(-1);
  for (std::size_t p = 0; p < element.properties.size(); ++p)
    if (const auto role = role_of(element.properties[p].name);
        role && !element.properties[p].count_type)
      layout.property[*role] = int(p);
  if (!layout.has(kX) || !layout.has(kY) || !layout.has(kZ))
    throw Malformed("has no x, y or z property");
  return layout;
}

// A colour channel in [0, 1]: integers over their type's maximum, floats as they are.
double channel(const Element& element, const VertexLayout& layout, std::span<const double> values,
               Role role) {
  if (!layout.has(role)) return role == kAlpha ? 1.0 : 0.0;
  const Type type = element.properties[std::size_t(layout.property[role])].type;
  const double value = values[std::size_t(layout.property[role])];
  if (!std::isfinite(value)) throw Malformed("a colour channel is not finite");
  return is_integer(type) ? value / info(type).max : value;
}

template <class Body>
void read_vertices(const Element& element, Body& body, PlyData& data, std::uint64_t& entry) {
  const VertexLayout layout = vertex_layout(element);
  if (element.count > std::numeric_limits<std::uint32_t>::max())
    throw Malformed("has more than 2^32 - 1 entries");
  ImportedMesh& mesh = data.mesh;
  mesh.positions.reserve(element.count);
  if (layout.normals()) mesh.normals.reserve(element.count);
  if (layout.colors()) mesh.colors.reserve(element.count);
  if (layout.uvs()) data.uvs.reserve(element.count);
  std::vector<double> values(element.properties.size());
  std::vector<std::int64_t> unused;
  auto get = [&](Role role) { return layout.has(role) ? float(values[layout.property[role]]) : 0; };
  for (entry = 0; entry < element.count; ++entry) {
    read_entry(element, body, values, values.size(), unused);
    mesh.positions.push_back({get(kX), get(kY), get(kZ)});
    if (layout.normals()) mesh.normals.push_back({get(kNx), get(kNy), get(kNz)});
    if (layout.uvs()) data.uvs.push_back({get(kU), get(kV)});
    if (!layout.colors()) continue;
    auto c = [&](Role role) { return channel(element, layout, values, role); };
    mesh.colors.push_back(pack_rgba8(c(kRed), c(kGreen), c(kBlue), c(kAlpha)));
  }
  data.has_vertices = true;
}

std::uint32_t vertex_index(std::int64_t index, std::size_t vertex_count) {
  if (index < 0 || std::uint64_t(index) >= vertex_count)
    throw Malformed("names vertex " + std::to_string(index) + " of " +
                    std::to_string(vertex_count) + " vertices");
  return std::uint32_t(index);
}

// A polygon fanned from its first vertex: n - 2 triangles.
void add_polygon(std::span<const std::int64_t> list, PlyData& data) {
  const std::size_t vertex_count = data.mesh.positions.size();
  for (const std::int64_t index : list) vertex_index(index, vertex_count);
  data.has_edges |= list.size() >= 2;
  for (std::size_t k = 1; k + 1 < list.size(); ++k)
    data.mesh.triangles.push_back(
        {{std::uint32_t(list[0]), std::uint32_t(list[k]), std::uint32_t(list[k + 1])}});
}

// Strips restarted by -1; odd triangles of a run swap their first two corners to keep the
// winding; triangles naming a vertex twice (the joints between strips) are left out.
void add_strips(std::span<const std::int64_t> list, PlyData& data) {
  const std::size_t vertex_count = data.mesh.positions.size();
  std::size_t run = 0;  // vertices since the last restart
  for (std::size_t i = 0; i < list.size(); ++i) {
    if (list[i] == -1) {
      run = 0;
      continue;
    }
    const std::uint32_t c = vertex_index(list[i], vertex_count);
    data.has_edges |= ++run >= 2;
    if (run < 3) continue;
    const auto a = std::uint32_t(list[i - 2]), b = std::uint32_t(list[i - 1]);
    if (a == b || b == c || a == c) continue;
    data.mesh.triangles.push_back(run % 2 == 1 ? format::Triangle{{a, b, c}}
                                               : format::Triangle{{b, a, c}});
  }
}

template <class Body>
void read_faces(const Element& element, Body& body, PlyData& data, std::uint64_t& entry) {
  if (!data.has_vertices) throw Malformed("comes before the vertex element");
  const auto found =
      std::find_if(element.properties.begin(), element.properties.end(), [](auto& p) {
        return p.count_type && (p.name == "vertex_indices" || p.name == "vertex_index");
      });
  if (found == element.properties.end()) throw Malformed("has no vertex_indices list");
  if (!is_integer(found->type)) throw Malformed("has vertex_indices that are not integers");
  const bool strips = element.name == "tristrips";
  std::vector<double> values(element.properties.size());
  std::vector<std::int64_t> list;
  for (entry = 0; entry < element.count; ++entry) {
    read_entry(element, body, values, std::size_t(found - element.properties.begin()), list);
    strips ? add_strips(list, data) : add_polygon(list, data);
  }
}

template <class Body>
void skip_entries(const Element& element, Body& body, std::uint64_t& entry) {
  std::vector<double> values(element.properties.size());
  std::vector<std::int64_t> unused;
  for (entry = 0; entry < element.count; ++entry)
    read_entry(element, body, values, values.size(), unused);
}

template <class Body>
PlyData read_elements(const std::string& path, const Header& header, Body body) {
  PlyData data;
  for (const Element& element : header.elements) {
    std::uint64_t entry = element.count;  // the readers count from 0 while inside the entries
    try {
      check_fits(element, body, header.encoding == Encoding::ascii);
      if (element.name == "vertex" && data.has_vertices) throw Malformed("appears twice");
      if (element.name == "vertex")
        read_vertices(element, body, data, entry);
      else if (element.name == "face" || element.name == "tristrips")
        read_faces(element, body, data, entry);
      else
        skip_entries(element, body, entry);
    } catch (const Malformed& e) {
      const std::string at = entry < element.count ? " " + std::to_string(entry) + body.where()
                                                   : std::string(" element");
      throw ImportError(path + ": " + printable(element.name) + at + ": " + e.what());
    }
  }
  if (!data.has_vertices) throw ImportError(path + ": has no vertex element");
  return data;
}

}  // namespace

std::vector<ImportedMesh> import_ply(const std::string& path, std::span<const std::byte> bytes) {
  const Header header = parse_header(path, bytes);
  const auto body = bytes.subspan(header.body_offset);
  PlyData data =
      header.encoding == Encoding::ascii
          ? read_elements(path, header, AsciiBody(body, header.body_line))
          : read_elements(path, header, BinaryBody(body, header.encoding == Encoding::big_endian));
  if (!data.mesh.triangles.empty()) join_identical_vertices(data.mesh, data.uvs);
  data.mesh.point_cloud = data.mesh.triangles.empty() && !data.has_edges;
  std::vector<ImportedMesh> meshes;
  meshes.push_back(std::move(data.mesh));
  return meshes;
}

}  // namespace kiln
