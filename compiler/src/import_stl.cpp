// Kiln's STL reader. Assimp 5.2.5 (Debian's) leaks on malformed ASCII STL (LeakSanitizer, found
// by import_stl_fuzzer), so Kiln reads STL itself, giving what the Assimp path gave:
// - Binary or ASCII as Assimp decided: binary when 84 + 50 * count is the file size, else ASCII
//   when the file starts with "solid" (after spaces and tabs), else neither.
// - Binary: one mesh named "", a normal per facet on its three vertices. A facet whose attribute
//   has bit 15 set is coloured (5 bits a channel, blue in the low bits; red there when the header
//   holds "COLOR=", Materialise style); then every other facet takes the default colour: 0.6 in
//   all four channels, or the four bytes after "COLOR=". (Materialise files mean bit 15 the other
//   way round; Assimp reads them as VisCAM ones, and so does Kiln, so colours stay as they were.)
// - ASCII: a mesh per solid, named by the word after "solid" (or ""), solids with no facets left
//   out. Keywords are case-sensitive and found word by word as Assimp found them: `facet normal
//   X Y Z`, `vertex X Y Z`, `endsolid` (to the end of its line); every other word (outer, loop,
//   endloop, endfacet) is skipped; a vertex before any facet or after a facet's third is ignored.
//   A NUL byte ends the text, as it ended Assimp's. Numbers are Assimp's (parse_real.hpp), but a
//   word that is not wholly a number is refused (Assimp read its numeric prefix, or threw).
// - A solid whose vertices are not three per normal is refused, as Assimp refused it.
// - Vertices joined as Assimp's JoinIdenticalVertices joined them (join_vertices.hpp).
// Non-finite coordinates pass through: assemble_scene drops their triangles, as for every format.
// Memory stays within a small multiple of the file size: a binary count is checked against the
// size before anything is allocated, and an ASCII vertex takes at least 13 bytes of text.
#include "import_stl.hpp"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>
#include <optional>
#include <string_view>

#include "join_vertices.hpp"
#include "kiln/compiler/import.hpp"
#include "parse_real.hpp"
#include "rgba8.hpp"

namespace kiln {

namespace {

constexpr std::size_t kHeaderSize = 84;  // 80 bytes of header, then the facet count
constexpr std::size_t kFacetSize = 50;   // normal, 3 vertices, 16-bit attribute

// At most 32 characters of `text`, control and non-ASCII bytes as '?': safe for a one-line error.
std::string printable(std::string_view text) {
  std::string out(text.substr(0, 32));
  for (char& c : out)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) > 0x7E) c = '?';
  return text.size() > 32 ? out + "..." : out;
}

std::uint32_t load_u32(const std::byte* p) {
  return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 |
         std::uint32_t(p[3]) << 24;
}

float load_f32(const std::byte* p) {
  return std::bit_cast<float>(load_u32(p));
}

// Assimp's size test, on the bytes from `at` on. Assimp computed 84 + 50 * count in 32 bits; so
// does Kiln, so that a count whose size wraps around is still taken for binary (and refused).
bool binary_at(std::span<const std::byte> bytes, std::size_t at) {
  const std::size_t size = bytes.size() - at;
  if (size < kHeaderSize) return false;
  const std::uint32_t count = load_u32(bytes.data() + at + 80);
  return std::uint32_t(count * std::uint32_t(kFacetSize) + kHeaderSize) == size;
}

// ---------------------------------------------------------------------------------------------
// Binary

struct Rgba {
  float r, g, b, a;
};

// The default colour of a Materialise file: the four bytes after "COLOR=" in the header. The scan
// is Assimp's: each byte compared is consumed, the mismatching one too, so a try starts after it
// (and "CCOLOR=" is not found); a match near byte 80 reads on into the count and the first facet.
std::optional<Rgba> materialise_color(std::span<const std::byte> bytes) {
  static constexpr char kKey[] = "COLOR=";
  std::size_t at = 0;
  while (at < 80) {
    std::size_t matched = 0;
    while (matched < 6 && char(bytes[at++]) == kKey[matched]) ++matched;
    if (matched < 6) continue;
    const float scale = 1.0f / 255.0f;
    auto channel = [&](std::size_t i) { return float(std::uint8_t(bytes[at + i])) * scale; };
    return Rgba{channel(0), channel(1), channel(2), channel(3)};
  }
  return std::nullopt;
}

// A facet's colour from bit 15 of its attribute: 5 bits a channel, as Assimp scaled them.
std::uint32_t facet_color(std::uint16_t attribute, bool materialise) {
  const float scale = 1.0f / 31.0f;
  const float low = float(attribute & 0x1Fu) * scale;
  const float mid = float((attribute >> 5) & 0x1Fu) * scale;
  const float high = float((attribute >> 10) & 0x1Fu) * scale;
  return materialise ? pack_rgba8(low, mid, high, 1.0) : pack_rgba8(high, mid, low, 1.0);
}

ImportedMesh read_binary(const std::string& path, std::span<const std::byte> bytes) {
  const std::uint32_t count = load_u32(bytes.data() + 80);
  const std::uint64_t needed = kHeaderSize + std::uint64_t(count) * kFacetSize;
  if (needed > bytes.size())
    throw ImportError(path + ": binary STL claims " + std::to_string(count) + " triangles (" +
                      std::to_string(needed) + " bytes), more than the file's " +
                      std::to_string(bytes.size()) + " bytes hold");
  if (count == 0) throw ImportError(path + ": binary STL with no triangles");
  const std::optional<Rgba> materialise = materialise_color(bytes);
  const Rgba fallback = materialise.value_or(Rgba{0.6f, 0.6f, 0.6f, 0.6f});
  ImportedMesh mesh;
  mesh.positions.reserve(std::size_t(count) * 3);
  mesh.normals.reserve(std::size_t(count) * 3);
  mesh.triangles.reserve(count);
  for (std::uint32_t f = 0; f < count; ++f) {
    const std::byte* facet = bytes.data() + kHeaderSize + std::size_t(f) * kFacetSize;
    auto vector = [&](int i) {
      return format::Float3{load_f32(facet + 12 * i), load_f32(facet + 12 * i + 4),
                            load_f32(facet + 12 * i + 8)};
    };
    for (int corner = 1; corner <= 3; ++corner) {
      mesh.positions.push_back(vector(corner));
      mesh.normals.push_back(vector(0));
    }
    mesh.triangles.push_back({{3 * f, 3 * f + 1, 3 * f + 2}});
    const auto attribute = std::uint16_t(std::uint16_t(facet[48]) | std::uint16_t(facet[49]) << 8);
    if ((attribute & 0x8000u) == 0) continue;
    // Assimp gave every vertex the default colour once the first coloured facet appeared.
    if (mesh.colors.empty())
      mesh.colors.assign(std::size_t(count) * 3,
                         pack_rgba8(fallback.r, fallback.g, fallback.b, fallback.a));
    const std::uint32_t color = facet_color(attribute, materialise.has_value());
    std::fill_n(mesh.colors.begin() + std::ptrdiff_t(f) * 3, 3, color);
  }
  return mesh;
}

// ---------------------------------------------------------------------------------------------
// ASCII

bool is_space(char c) {
  return c == ' ' || c == '\t';
}
bool is_line_end(char c) {  // Assimp's IsLineEnd: the NUL that ends the text counts
  return c == '\r' || c == '\n' || c == '\0' || c == '\f';
}
bool is_separator(char c) {
  return is_space(c) || is_line_end(c);
}

// The text walked as Assimp's STL loader walked it; at() reads '\0' at and past the end.
class AsciiReader {
 public:
  AsciiReader(const std::string& path, std::span<const std::byte> bytes)
      : path_(path),
        bytes_(bytes),
        text_(reinterpret_cast<const char*>(bytes.data()), bytes.size()) {
    text_ = text_.substr(0, text_.find('\0'));  // Assimp's C strings ended at a NUL
  }

  // Assimp's IsAsciiSTL at the reading position: not binary-sized from here, and "solid" after
  // spaces and tabs, with more bytes behind it.
  bool at_solid() const {
    if (binary_at(bytes_, at_)) return false;
    std::size_t at = at_;
    while (is_space(char_at(at))) ++at;
    return at + 5 < bytes_.size() && text_.compare(std::min(at, text_.size()), 5, "solid") == 0;
  }

  ImportedMesh read_solid();

 private:
  char char_at(std::size_t at) const { return at < text_.size() ? text_[at] : '\0'; }
  char at(std::size_t offset = 0) const { return char_at(at_ + offset); }
  bool word(std::string_view w) const {
    return text_.compare(std::min(at_, text_.size()), w.size(), w) == 0;
  }
  void skip_spaces() {
    while (is_space(at())) ++at_;
  }
  bool skip_spaces_and_line_ends() {  // false at the end of the text
    while (is_space(at()) || at() == '\r' || at() == '\n') ++at_;
    return at() != '\0';
  }
  void skip_word() {
    do ++at_;
    while (!is_separator(at()));
  }
  [[noreturn]] void fail(const std::string& what) const {
    const std::size_t end = std::min(at_, text_.size());
    const auto line = 1 + std::count(text_.begin(), text_.begin() + std::ptrdiff_t(end), '\n');
    throw ImportError(path_ + ": line " + std::to_string(line) + ": " + what);
  }
  float number(const char* what);
  format::Float3 vector(const char* what) {
    const float x = number(what), y = number(what), z = number(what);
    return {x, y, z};
  }

  const std::string& path_;
  std::span<const std::byte> bytes_;
  std::string_view text_;
  std::size_t at_ = 0;
};

// The next word on the line as a number, all of it (Assimp also stopped at its end, reading
// "1.5abc" as 1.5 and throwing on "abc"; Kiln refuses both).
float AsciiReader::number(const char* what) {
  skip_spaces();
  const std::size_t start = at_;
  while (!is_separator(at())) ++at_;
  const std::string_view token = text_.substr(std::min(start, text_.size()), at_ - start);
  if (token.empty()) fail(std::string(what) + " has fewer than 3 numbers");
  const std::optional<float> value = parse_real<float>(token);
  if (!value) fail(std::string(what) + ": '" + printable(token) + "' is not a number");
  return *value;
}

// One solid, from "solid" to past "endsolid" (or the end of the text).
ImportedMesh AsciiReader::read_solid() {
  ImportedMesh mesh;
  skip_spaces();
  at_ += 5;
  skip_spaces();
  const std::size_t name_start = at_;
  while (!is_separator(at())) ++at_;
  mesh.name = std::string(text_.substr(std::min(name_start, text_.size()), at_ - name_start));
  if (mesh.name.size() >= 1024) fail("a solid name of 1024 characters or more");  // as Assimp
  std::vector<format::Float3> normals;  // three per facet with a normal, as Assimp kept them
  unsigned corners = 3;                 // of the current facet; no facet yet: vertices ignored
  while (skip_spaces_and_line_ends()) {
    if (word("facet") && is_separator(at(5)) && at(5) != '\0') {
      corners = 0;
      at_ += 6;
      skip_spaces();
      if (!word("normal")) continue;  // the count check below refuses the solid
      if (at(6) == '\0') fail("the file ends inside a facet");
      at_ += 7;
      normals.insert(normals.end(), 3, vector("a facet normal"));
    } else if (word("vertex") && is_separator(at(6)) && corners < 3) {
      if (at(6) == '\0') fail("the file ends inside a facet");
      at_ += 7;
      mesh.positions.push_back(vector("a vertex"));
      ++corners;
    } else if (word("endsolid")) {
      while (!is_line_end(at())) ++at_;
      skip_spaces_and_line_ends();
      break;
    } else {
      skip_word();
    }
  }
  const std::size_t vertices = mesh.positions.size();
  if (vertices % 3 != 0 || normals.size() != vertices)
    fail("solid '" + printable(mesh.name) + "' has " + std::to_string(vertices) + " vertices and " +
         std::to_string(normals.size() / 3) +
         " facet normals; a facet needs a normal and 3 vertices");
  mesh.normals = std::move(normals);
  for (std::uint32_t v = 0; v < vertices; v += 3) mesh.triangles.push_back({{v, v + 1, v + 2}});
  return mesh;
}

[[noreturn]] void refuse_unknown(const std::string& path, std::span<const std::byte> bytes) {
  if (bytes.size() < kHeaderSize)
    throw ImportError(path + ": not an STL file (no 'solid' at the start, and " +
                      std::to_string(bytes.size()) + " bytes are too few for binary)");
  const std::uint32_t count = load_u32(bytes.data() + 80);
  throw ImportError(path + ": not an STL file (no 'solid' at the start, and the binary count of " +
                    std::to_string(count) + " triangles needs " +
                    std::to_string(kHeaderSize + std::uint64_t(count) * kFacetSize) +
                    " bytes, not " + std::to_string(bytes.size()) + ")");
}

// A file that starts with "solid" but has no facets may be a binary one of the wrong size.
[[noreturn]] void refuse_empty_ascii(const std::string& path, std::span<const std::byte> bytes) {
  std::string reason = path + ": ASCII STL with no facets";
  if (bytes.size() >= kHeaderSize) {
    const std::uint32_t count = load_u32(bytes.data() + 80);
    reason += " (read as binary, its count of " + std::to_string(count) + " triangles needs " +
              std::to_string(kHeaderSize + std::uint64_t(count) * kFacetSize) + " bytes, not " +
              std::to_string(bytes.size()) + ")";
  }
  throw ImportError(reason);
}

}  // namespace

bool is_binary_stl(std::span<const std::byte> bytes) {
  return binary_at(bytes, 0);
}

std::vector<ImportedMesh> import_stl(const std::string& path, std::span<const std::byte> bytes) {
  std::vector<ImportedMesh> meshes;
  if (is_binary_stl(bytes)) {
    meshes.push_back(read_binary(path, bytes));
  } else {
    AsciiReader reader(path, bytes);
    if (!reader.at_solid()) refuse_unknown(path, bytes);
    while (reader.at_solid())
      if (ImportedMesh mesh = reader.read_solid(); !mesh.triangles.empty())
        meshes.push_back(std::move(mesh));
    if (meshes.empty()) refuse_empty_ascii(path, bytes);
  }
  for (ImportedMesh& mesh : meshes) join_identical_vertices(mesh);
  return meshes;
}

}  // namespace kiln
