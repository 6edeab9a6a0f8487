// Kiln's OBJ reader. Assimp 5.2.5 allocates and fills a 16 MiB line buffer twice per OBJ (0.66 ms
// for a tiny file), too slow to fuzz, so Kiln reads OBJ itself and gives what the Assimp path
// gave (read, Triangulate, JoinIdenticalVertices, converted):
// - Lines end at \r, \n, \0 or \f; a backslash just before one joins the next line. A line is
//   read by its first character only (an indented line is skipped): `v` (3 numbers; 4:
//   homogeneous; 6: with a colour; any other count: ignored), `vt` (2 or 3), `vn`, `f`/`l`/`p`
//   (and any word starting so), `usemtl`, `mtllib`, `g`, `o`, `cstype` ... `end` skipped.
// - Numbers as Assimp's fast_atof reads them (a prefix; ',' is a decimal point too), face
//   indices as atoi read them, stepping by the digits of the value as Assimp did.
// - A mesh per object (`o`), group (`g` when the name changes) and material change inside them
//   (`usemtl` after faces); forward vertex references are allowed; every corner is its own vertex
//   until joined. Quads fan from their concave corner, larger polygons are ear-clipped, both
//   exactly as TriangulateProcess did (its n-gon corner rotation included).
// - Vertices of a mesh are joined when their positions are equal and their normals and texture
//   coordinates within 1e-5, keeping the first, numbered in order of first use, as
//   JoinIdenticalVertices did (colours are not compared, as there).
// - Base colours: the .mtl's Kd for materials that differ from Assimp's default material. The
//   .mtl is looked for as Assimp's FileSystemFilter looked, every probe recorded in FileAccesses.
// - No face, `o` or `g` at all: one point cloud of all vertices, named after the file.
// Where Kiln differs, on purpose or as a known approximation:
// - Assimp read past the end of a line (a fourth '/' field in a face corner) or crashed (MTL
//   statements before any `newmtl`); Kiln ends the face or ignores the statement.
// - Read from memory (.zst, UTF-16, fuzzers) Kiln opens no .mtl (Assimp looked in the working
//   directory, then parsed the OBJ itself as the .mtl) and names a point cloud after the file
//   (Assimp: "$$$___magic___$$$.obj").
// - Assimp's hash map could join distinct positions within 1e-5 that fell in one bucket; Kiln
//   joins equal positions only, as its PLY reader does.
// - Deciding whether a material equals the default, texture options (-clamp, -bm) are not
//   compared, and a UTF-16 .mtl is not transcoded.
#include "import_obj.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string_view>
#include <unordered_map>
#include <utility>

#include "rgba8.hpp"

namespace kiln {

void check_obj_faces(const std::string& path, std::span<const std::byte> bytes,
                     std::uint32_t limit) {
  const auto* text = reinterpret_cast<const char*>(bytes.data());
  const std::size_t size = bytes.size();
  std::size_t line = 1;
  for (std::size_t i = 0; i < size;) {
    const std::size_t first_line = line;
    while (i < size && (text[i] == ' ' || text[i] == '\t')) ++i;
    const bool face = i + 1 < size && text[i] == 'f' && (text[i + 1] == ' ' || text[i + 1] == '\t');
    std::uint64_t corners = 0;
    bool in_token = false;
    for (i += face ? 1 : 0; i < size && text[i] != '\n'; ++i) {
      if (text[i] == '\\' && i + 1 < size && (text[i + 1] == '\n' || text[i + 1] == '\r')) {
        i += text[i + 1] == '\r' && i + 2 < size && text[i + 2] == '\n' ? 2 : 1;
        ++line;
        in_token = false;
        continue;
      }
      const bool space = text[i] == ' ' || text[i] == '\t' || text[i] == '\r';
      if (face && !space && !in_token) ++corners;
      in_token = !space;
    }
    if (corners > limit)
      throw ImportError(path + ":" + std::to_string(first_line) + ": a face with " +
                        std::to_string(corners) + " corners; the limit is " +
                        std::to_string(limit) + " (raise it with --max-face-vertices)");
    ++i;
    ++line;
  }
}

namespace {

// A fault in the line being read; read_lines adds the file and line.
class Malformed : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

bool is_line_end(char c) {
  return c == '\r' || c == '\n' || c == '\0' || c == '\f';
}
bool is_space(char c) {
  return c == ' ' || c == '\t';
}
bool is_digit(char c) {
  return c >= '0' && c <= '9';
}

// At most 32 characters of `text`, control and non-ASCII bytes as '?': safe for a one-line error.
std::string printable(std::string_view text) {
  std::string out(text.substr(0, 32));
  for (char& c : out)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) > 0x7E) c = '?';
  return text.size() > 32 ? out + "..." : out;
}

// An aiString set from `name`: Assimp leaves names of 1024 bytes or more empty.
std::string ai_name(const std::string& name) {
  return name.size() > 1023 ? std::string() : name;
}

// ---------------------------------------------------------------------------------------------
// Numbers as Assimp 5.2.5 reads them

// strtoul10_64: the digits at `at` (none: Assimp throws). On overflow it gives 0 and leaves `at`
// where it was; with `max_digits`, digits past the first that many are skipped.
std::optional<std::uint64_t> assimp_digits(std::string_view s, std::size_t& at,
                                           unsigned* max_digits) {
  if (at >= s.size() || !is_digit(s[at])) return std::nullopt;
  std::uint64_t value = 0;
  unsigned count = 0;
  std::size_t i = at;
  for (; i < s.size() && is_digit(s[i]); ++i) {
    const std::uint64_t next = value * 10 + std::uint64_t(s[i] - '0');
    if (next < value) return 0;
    value = next;
    if (max_digits != nullptr && *max_digits == ++count) {
      for (++i; i < s.size() && is_digit(s[i]);) ++i;
      at = i;
      return value;
    }
  }
  at = i;
  if (max_digits != nullptr) *max_digits = count;
  return value;
}

bool starts_ci(std::string_view s, std::size_t at, std::string_view word) {
  if (s.size() - std::min(at, s.size()) < word.size()) return false;
  for (std::size_t i = 0; i < word.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(s[at + i])) != word[i]) return false;
  return true;
}

// fast_atoreal_move<float>: the number at the start of `word`, the rest ignored; none where
// Assimp threw (no digit first, a bare exponent). The integer part in uint64 then float, at
// most 15 decimals scaled in double, the exponent applied as powf(10, e); "-nan" is NaN.
std::optional<float> assimp_atof(std::string_view s) {
  static constexpr double kScale[16] = {0,    1e-1, 1e-2,  1e-3,  1e-4,  1e-5,  1e-6,  1e-7,
                                        1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 1e-14, 1e-15};
  std::size_t at = 0;
  const bool negative = !s.empty() && s[0] == '-';
  if (!s.empty() && (s[0] == '-' || s[0] == '+')) ++at;
  if (starts_ci(s, at, "nan")) return std::numeric_limits<float>::quiet_NaN();
  if (starts_ci(s, at, "inf"))
    return negative ? -std::numeric_limits<float>::infinity()
                    : std::numeric_limits<float>::infinity();
  auto digit = [&](std::size_t i) { return i < s.size() && is_digit(s[i]); };
  auto point = [&](std::size_t i) { return i < s.size() && (s[i] == '.' || s[i] == ','); };
  if (!digit(at) && !(point(at) && digit(at + 1))) return std::nullopt;
  float f = 0;
  if (!point(at)) f = float(*assimp_digits(s, at, nullptr));
  if (point(at) && digit(at + 1)) {
    ++at;
    unsigned used = 15;
    const double decimals = double(*assimp_digits(s, at, &used));
    f += float(decimals * kScale[used]);
  } else if (at < s.size() && s[at] == '.') {
    ++at;
  }
  if (at < s.size() && (s[at] == 'e' || s[at] == 'E')) {
    ++at;
    const bool negative_exponent = at < s.size() && s[at] == '-';
    if (at < s.size() && (s[at] == '-' || s[at] == '+')) ++at;
    const auto exponent = assimp_digits(s, at, nullptr);
    if (!exponent) return std::nullopt;
    const float e = float(*exponent);
    f *= std::pow(10.0f, negative_exponent ? -e : e);
  }
  return negative ? -f : f;
}

float number(std::string_view word) {
  const auto value = assimp_atof(word);
  if (!value) throw Malformed("'" + printable(word) + "' is not a number");
  return *value;
}

// C's atoi at `at` (leading white space, a sign, digits; strtol's clamping, then int).
int c_atoi(std::string_view s, std::size_t at) {
  while (at < s.size() && std::strchr(" \t\n\v\f\r", s[at]) != nullptr && s[at] != '\0') ++at;
  const bool negative = at < s.size() && s[at] == '-';
  if (at < s.size() && (s[at] == '-' || s[at] == '+')) ++at;
  constexpr std::uint64_t kLimit = std::uint64_t(1) << 63;
  std::uint64_t magnitude = 0;
  for (; at < s.size() && is_digit(s[at]); ++at)
    magnitude = std::min(kLimit, magnitude * 10 + std::uint64_t(s[at] - '0'));
  const std::int64_t value = negative
                                 ? (magnitude >= kLimit ? std::numeric_limits<std::int64_t>::min()
                                                        : -std::int64_t(magnitude))
                                 : std::int64_t(std::min(magnitude, kLimit - 1));
  return static_cast<int>(static_cast<std::uint32_t>(std::uint64_t(value)));
}

// ---------------------------------------------------------------------------------------------
// Lines, as IOStreamBuffer::getNextDataLine cut them

class LineReader {
 public:
  explicit LineReader(std::string_view text) : text_(text) {}
  std::size_t line_number() const {
    return 1 + std::size_t(std::count(text_.begin(), text_.begin() + start_, '\n'));
  }

  // The next line, up to its first line end. After a joining backslash Assimp skips past the
  // next '\n' and takes the character there whatever it is, so a line end there ends the line.
  bool next(std::string_view& line) {
    if (at_ >= text_.size()) return false;
    start_ = at_;
    bool joined = false;
    for (;;) {
      if (get(at_) == '\\' && is_line_end(get(at_ + 1))) {
        if (!joined) joined_.assign(text_.substr(start_, at_ - start_));
        joined = true;
        for (++at_; get(at_) != '\n';) ++at_;
        ++at_;
      } else if (is_line_end(get(at_))) {
        break;
      }
      if (joined) joined_.push_back(get(at_));
      if (++at_ >= text_.size()) break;
    }
    line = joined ? std::string_view(joined_) : text_.substr(start_, at_ - start_);
    ++at_;
    line =
        line.substr(0, std::min(line.size(), line.find_first_of(std::string_view("\r\n\0\f", 4))));
    return true;
  }

 private:
  char get(std::size_t i) const { return i < text_.size() ? text_[i] : '\n'; }  // as Assimp's fill
  std::string_view text_;
  std::size_t at_ = 0, start_ = 0;
  std::string joined_;
};

// copyNextWord: spaces skipped (and a backslash with the character after it), then at most 4095
// characters up to a space; the 4095th is read again as the next word's first, as in Assimp.
std::string_view next_word(std::string_view s, std::size_t& at) {
  while (at < s.size() && is_space(s[at])) ++at;
  if (at < s.size() && s[at] == '\\') {
    at = std::min(at + 2, s.size());
    while (at < s.size() && is_space(s[at])) ++at;
  }
  const std::size_t start = at;
  std::size_t count = 0;
  while (at < s.size() && !is_space(s[at])) {
    if (++count == 4095) break;
    ++at;
  }
  return s.substr(start, count);
}

// getNextToken: past the keyword at `at` and the spaces after it.
std::size_t after_keyword(std::string_view s, std::size_t at = 0) {
  while (at < s.size() && !is_space(s[at])) ++at;
  while (at < s.size() && is_space(s[at])) ++at;
  return at;
}

std::string_view first_word(std::string_view s) {
  return s.substr(0, std::min(s.size(), s.find_first_of(" \t")));
}

std::string_view trim_end(std::string_view s) {
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

// ---------------------------------------------------------------------------------------------
// The model, as Assimp's ObjFile::Model held it

struct Vec3 {
  float x = 0, y = 0, z = 0;
};

enum class Prim : std::uint8_t { polygon, line, point };

struct Face {
  std::uint64_t first;  // vertex, then texture, then normal indices, in Model::indices
  std::uint32_t nv, nt, nn;
  Prim prim;
};

constexpr std::uint32_t kNoMaterial = ~0u;

struct ObjMesh {
  std::string name;
  std::vector<Face> faces;
  std::uint32_t material = kNoMaterial;
  bool has_normals = false;
  std::uint64_t uv_corners = 0;
};

struct ObjObject {
  std::string name;
  std::vector<std::uint32_t> meshes;
};

enum Texture : std::uint8_t {
  kDiffuseMap,
  kAmbientMap,
  kSpecularMap,
  kDisplacementMap,
  kOpacityMap,
  kEmissiveMap,
  kBumpMap,
  kNormalMap,
  kShininessMap,
  kRoughnessMap,
  kMetallicMap,
  kSheenMap,
  kTextures
};

struct Material {
  std::string name;
  Vec3 ambient, diffuse{0.6f, 0.6f, 0.6f}, specular, emissive, transparent{1, 1, 1};
  float alpha = 1, shininess = 0, ior = 1, anisotropy = 0;
  int illumination = 1;
  std::array<std::optional<float>, 4> factors;  // roughness, metallic, clearcoat, its roughness
  std::optional<Vec3> sheen;
  std::array<std::string, kTextures> textures;
};

struct Model {
  std::vector<Vec3> vertices, normals, uvs, colors;
  std::vector<std::uint32_t> indices;
  std::vector<ObjMesh> meshes;
  std::vector<ObjObject> objects;
  std::vector<Material> materials;  // Assimp's material library order; [0] is its default
  std::unordered_map<std::string, std::uint32_t> material_index;
  // The first object of each name (Assimp searched them in order, in quadratic time).
  std::unordered_map<std::string, std::uint32_t> object_index;
  int current_material = -1, current_object = -1, current_mesh = -1;
  std::string active_group;
};

std::uint32_t add_material(Model& model, const std::string& name) {
  const auto index = std::uint32_t(model.materials.size());
  model.materials.push_back(Material{});
  model.materials.back().name = name;
  model.material_index.emplace(name, index);
  return index;
}

// ---------------------------------------------------------------------------------------------
// The .mtl, as ObjFileMtlImporter read it: line by line on the first character, into the
// model's current material (which the OBJ may have set before `mtllib`).

class MtlReader {
 public:
  explicit MtlReader(Model& model) : model_(model) {}
  void read(std::string_view text) {
    std::size_t at = 0;
    while (at < text.size()) {
      std::size_t end = at;
      while (end < text.size() && !is_line_end(text[end])) ++end;
      line(text.substr(at, end - at));
      for (at = end + 1; at < text.size() && is_space(text[at]);) ++at;  // skipLine's tail
    }
  }

 private:
  Material* current() {
    return model_.current_material < 0 ? nullptr : &model_.materials[model_.current_material];
  }
  char at(std::string_view s, std::size_t i) const { return i < s.size() ? s[i] : '\n'; }

  static std::string_view word(std::string_view s, std::size_t& at) {
    while (at < s.size() && is_space(s[at])) ++at;
    const std::size_t start = at;
    while (at < s.size() && !is_space(s[at])) ++at;
    return s.substr(start, at - start);
  }
  // getColorRGBA: r, then g and b unless the line ends right after r.
  static Vec3 color(std::string_view s, std::size_t at) {
    Vec3 c;
    c.x = number(word(s, at));
    if (at < s.size()) {
      c.y = number(word(s, at));
      c.z = number(word(s, at));
    }
    return c;
  }
  static float value(std::string_view s, std::size_t at) {
    const std::string_view w = word(s, at);
    return w.empty() ? 0.0f : number(w);
  }
  static std::optional<float> maybe(std::string_view s, std::size_t at) {
    const std::string_view w = word(s, at);
    return w.empty() ? std::nullopt : std::optional<float>(number(w));
  }

  void line(std::string_view s) {
    Material* m = current();
    switch (at(s, 0)) {
      case 'k':
      case 'K':
        if (m == nullptr) return;
        if (at(s, 1) == 'a') m->ambient = color(s, 2);
        if (at(s, 1) == 'd') m->diffuse = color(s, 2);
        if (at(s, 1) == 's') m->specular = color(s, 2);
        if (at(s, 1) == 'e') m->emissive = color(s, 2);
        return;
      case 'T':
        if (at(s, 1) == 'f' && m != nullptr) m->transparent = color(s, 2);
        if (at(s, 1) == 'r') {
          const float d = value(s, 2);  // read (and checked) even without a material
          if (m != nullptr) m->alpha = 1.0f - d;
        }
        return;
      case 'd':
        if (s.substr(1, 3) == "isp") return texture(s);
        if (m != nullptr) m->alpha = value(s, 1);
        return;
      case 'N':
      case 'n':
        return n_line(s, m);
      case 'P':
        return p_line(s, m);
      case 'm':
      case 'b':
      case 'r':
        return texture(s);
      case 'i':
        if (m != nullptr) {
          std::size_t i = after_keyword(s);
          m->illumination = c_atoi(word(s, i), 0);
        }
        return;
      case 'a':
        if (m != nullptr) m->anisotropy = value(s, 1);  // Assimp crashed without a material
        return;
      default:
        return;
    }
  }

  void n_line(std::string_view s, Material* m) {
    switch (at(s, 1)) {
      case 's':
        if (m != nullptr) m->shininess = value(s, 2);
        return;
      case 'i':
        if (m != nullptr) m->ior = value(s, 2);
        return;
      case 'e':
        return new_material(s.substr(1));
      case 'o':
        return texture(s);
      default:
        return;
    }
  }

  void p_line(std::string_view s, Material* m) {
    if (m == nullptr) return;
    switch (at(s, 1)) {
      case 'r':
        m->factors[0] = maybe(s, 2);
        return;
      case 'm':
        m->factors[1] = maybe(s, 2);
        return;
      case 's':
        m->sheen = color(s, 2);
        return;
      case 'c':
        if (at(s, 2) == 'r')
          m->factors[3] = maybe(s, 3);
        else
          m->factors[2] = maybe(s, 2);
        return;
      default:
        return;
    }
  }

  // createMaterial: `s` starts after the 'n' of newmtl; a lone word names DefaultMaterial.
  void new_material(std::string_view s) {
    std::string name = "DefaultMaterial";
    const std::size_t gap = s.find_first_of(" \t");
    const std::size_t start = gap == std::string_view::npos ? gap : s.find_first_not_of(" \t", gap);
    if (start != std::string_view::npos) name = std::string(trim_end(s.substr(start)));
    if (const auto found = model_.material_index.find(name); found != model_.material_index.end()) {
      model_.current_material = int(found->second);
      return;
    }
    model_.current_material = int(add_material(model_, name));
    if (model_.current_mesh >= 0)
      model_.meshes[model_.current_mesh].material = std::uint32_t(model_.current_material);
  }

  // getTexture: the map's slot by its keyword, options skipped, the rest of the line its name.
  void texture(std::string_view s) {
    static constexpr std::pair<std::string_view, Texture> kKeywords[] = {
        {"map_kd", kDiffuseMap},
        {"map_ka", kAmbientMap},
        {"map_ks", kSpecularMap},
        {"map_disp", kDisplacementMap},
        {"disp", kDisplacementMap},
        {"map_d", kOpacityMap},
        {"map_emissive", kEmissiveMap},
        {"map_ke", kEmissiveMap},
        {"map_bump", kBumpMap},
        {"bump", kBumpMap},
        {"map_kn", kNormalMap},
        {"norm", kNormalMap},
        {"refl", kTextures},
        {"map_ns", kShininessMap},
        {"map_pr", kRoughnessMap},
        {"map_pm", kMetallicMap},
        {"map_ps", kSheenMap}};
    Material* m = current();
    const auto found = std::find_if(std::begin(kKeywords), std::end(kKeywords),
                                    [&](const auto& k) { return starts_ci(s, 0, k.first); });
    if (found == std::end(kKeywords) || found->second == kTextures || m == nullptr) return;
    std::size_t at = after_keyword(s);
    while (at < s.size() && s[at] == '-') {
      int skip = 1;
      for (const auto& [option, count] : {std::pair<std::string_view, int>{"-clamp", 2},
                                          {"-type", 2},
                                          {"-bm", 2},
                                          {"-blendu", 2},
                                          {"-blendv", 2},
                                          {"-boost", 2},
                                          {"-texres", 2},
                                          {"-imfchan", 2},
                                          {"-mm", 3},
                                          {"-o", 4},
                                          {"-s", 4},
                                          {"-t", 4}})
        if (starts_ci(s, at, option)) {
          skip = count;
          break;
        }
      for (int i = 0; i < skip; ++i) at = after_keyword(s, at);
    }
    m->textures[found->second] = std::string(s.substr(at));
  }

  Model& model_;
};

// Two materials with the same properties, the name aside: what Kiln's is_renamed_copy tested on
// Assimp's materials (floats bit for bit).
bool same_properties(const Material& a, const Material& b) {
  auto bits = [](const Vec3& v) {
    return std::array{std::bit_cast<std::uint32_t>(v.x), std::bit_cast<std::uint32_t>(v.y),
                      std::bit_cast<std::uint32_t>(v.z)};
  };
  auto same = [](float x, float y) {
    return std::bit_cast<std::uint32_t>(x) == std::bit_cast<std::uint32_t>(y);
  };
  auto same_maybe = [&](const std::optional<float>& x, const std::optional<float>& y) {
    return x.has_value() == y.has_value() && (!x || same(*x, *y));
  };
  for (std::size_t i = 0; i < a.factors.size(); ++i)
    if (!same_maybe(a.factors[i], b.factors[i])) return false;
  return bits(a.ambient) == bits(b.ambient) && bits(a.diffuse) == bits(b.diffuse) &&
         bits(a.specular) == bits(b.specular) && bits(a.emissive) == bits(b.emissive) &&
         bits(a.transparent) == bits(b.transparent) && same(a.alpha, b.alpha) &&
         same(a.shininess, b.shininess) && same(a.ior, b.ior) && same(a.anisotropy, b.anisotropy) &&
         a.illumination == b.illumination && a.sheen.has_value() == b.sheen.has_value() &&
         (!a.sheen || bits(*a.sheen) == bits(*b.sheen)) && a.textures == b.textures;
}

// The base colour the Assimp path took from a material: none for the default material, a
// material named like it, a name Assimp could not hold, or a renamed copy of the default
// (a `usemtl` no .mtl defines).
std::optional<std::array<float, 4>> base_color(const Model& model, std::uint32_t index) {
  const Material& m = model.materials[index == kNoMaterial ? 0 : index];
  const std::string name = ai_name(m.name);
  if (name.empty() || name == "DefaultMaterial" || same_properties(m, model.materials[0]))
    return std::nullopt;
  return std::array{m.diffuse.x, m.diffuse.y, m.diffuse.z, 1.0f};
}

// ---------------------------------------------------------------------------------------------
// Companion files as Assimp looked for them: its DefaultIOSystem behind the FileSystemFilter
// that retries a missing name against the OBJ's folder, each probe recorded as Kiln's
// RecordingIOSystem did (opened: read; looked for in vain: missing).

class CompanionFiles {
 public:
  CompanionFiles(const std::string& obj_path, FileAccesses* accessed) : accessed_(accessed) {
    const std::size_t slash = obj_path.find_last_of("\\/");
    base_ = slash == std::string::npos ? std::string() : obj_path.substr(0, slash);
    if (base_.empty()) base_ = ".";
    if (base_.back() != '/' && base_.back() != '\\') base_ += '/';
  }

  // FileSystemFilter::Open: the name, then as BuildPath finds it, then cleaned up.
  std::optional<std::string> open(const std::string& name) {
    if (auto text = read(name)) return text;
    std::string built = name;
    build_path(built);
    if (auto text = read(built)) return text;
    std::string cleaned = name;
    cleanup(cleaned);
    build_path(cleaned);
    return read(cleaned);
  }

 private:
  bool exists(const std::string& name) const {
    std::FILE* file = std::fopen(name.c_str(), "rb");
    if (file != nullptr) std::fclose(file);
    if (file == nullptr && !name.empty() && accessed_ != nullptr)
      accessed_->missing.push_back(name);
    return file != nullptr;
  }

  std::optional<std::string> read(const std::string& name) {
    std::FILE* file = std::fopen(name.c_str(), "rb");
    if (!name.empty() && accessed_ != nullptr)
      (file != nullptr ? accessed_->read : accessed_->missing).push_back(name);
    if (file == nullptr) return std::nullopt;
    std::string text;
    char chunk[65536];
    for (std::size_t got; (got = std::fread(chunk, 1, sizeof chunk, file)) > 0;)
      text.append(chunk, got);
    std::fclose(file);
    return text;
  }

  void build_path(std::string& in) const {
    if (in.size() < 3 || exists(in)) return;
    if (in[1] != ':' && exists(base_ + in)) {
      in = base_ + in;
      return;
    }
    std::size_t pos = in.rfind('/');
    if (pos == std::string::npos) pos = in.rfind('\\');
    if (pos == std::string::npos) return;
    for (std::size_t last = std::string::npos;;) {
      std::size_t sep = in.rfind('/', last);
      if (sep == std::string::npos) sep = in.rfind('\\', last);
      if (sep == std::string::npos || sep == 0) return;
      last = sep - 1;
      const std::string candidate = base_ + '/' + in.substr(sep + 1, in.size() - pos);
      if (exists(candidate)) {
        in = candidate;
        return;
      }
    }
  }

  // FileSystemFilter::Cleanup: leading white space dropped (with one character more, as
  // there), separators made '/' and runs of them collapsed, "://" kept.
  static void cleanup(std::string& in) {
    if (in.empty()) return;
    std::size_t lead = 0;
    while (lead < in.size() && (is_space(in[lead]) || is_line_end(in[lead]))) ++lead;
    if (lead > 0) in.erase(0, std::min(in.size(), lead + 1));
    std::string out;
    char last = 0;
    for (std::size_t i = 0; i < in.size(); ++i) {
      if (in.compare(i, 3, "://") == 0) {
        out.append(in, i, 4);
        i += 3;
        continue;
      }
      if (i == 0 && in.compare(0, 2, "\\\\") == 0) {
        out.append(in, 0, 3);
        i += 2;
        continue;
      }
      char c = in[i] == '\\' ? '/' : in[i];
      if (c == '/' && last == '/') continue;
      out.push_back(c);
      last = c;
    }
    in = std::move(out);
  }

  std::string base_;
  FileAccesses* accessed_;
};

// ---------------------------------------------------------------------------------------------
// OBJ statements, as ObjFileParser read them

class ObjParser {
 public:
  ObjParser(const std::string& path, bool companions, std::uint32_t max_corners,
            FileAccesses* accessed)
      : path_(path), companions_(companions), max_corners_(max_corners), accessed_(accessed) {
    add_material(model_, "DefaultMaterial");
  }
  Model& model() { return model_; }

  void read(std::string_view text) {
    LineReader lines(text);
    std::string_view s;
    while (lines.next(s)) {
      try {
        line(s);
      } catch (const Malformed& e) {
        throw ImportError(path_ + ":" + std::to_string(lines.line_number()) + ": " + e.what());
      }
    }
  }

 private:
  void line(std::string_view s) {
    const char c = s.empty() ? '\n' : s[0];
    if (in_cstype_) {
      if (c == 'e') in_cstype_ = first_word(s) != "end";
      return;
    }
    switch (c) {
      case 'v':
        return vertex_line(s);
      case 'p':
      case 'l':
      case 'f':
        return face(s, c == 'f' ? Prim::polygon : c == 'l' ? Prim::line : Prim::point);
      case 'u':
        if (first_word(s) == "usemtl") use_material(s);
        return;
      case 'm':
        if (first_word(s) == "mtllib") material_library(s);
        return;
      case 'g':
        return group(s);
      case 'o':
        return object(s);
      case 'c':
        in_cstype_ = first_word(s) == "cstype";
        return;
      default:
        return;  // comments, `s`, `mg` and anything else
    }
  }

  // getNumComponentsInDataDefinition: the words from `at` that start like a number.
  static std::size_t numeric_words(std::string_view s, std::size_t at) {
    std::size_t count = 0;
    while (true) {
      while (at < s.size() && is_space(s[at])) ++at;
      if (at >= s.size()) return count;
      const char c = s[at];
      if (is_digit(c) || c == '-' || c == '+' || starts_ci(s, at, "nan") || starts_ci(s, at, "inf"))
        ++count;
      while (at < s.size() && !is_space(s[at])) ++at;
    }
  }

  static Vec3 vector3(std::string_view s, std::size_t at) {
    Vec3 v;
    v.x = number(next_word(s, at));
    v.y = number(next_word(s, at));
    v.z = number(next_word(s, at));
    return v;
  }

  void vertex_line(std::string_view s) {
    const char kind = s.size() > 1 ? s[1] : '\n';
    if (kind == 't') return texture_coordinate(s);
    if (kind == 'n') return model_.normals.push_back(vector3(s, 2));
    if (kind != ' ' && kind != '\t') return;
    const std::size_t count = numeric_words(s, 1);
    if (count == 3) return model_.vertices.push_back(vector3(s, 1));
    if (count == 6) {
      std::size_t at = 1;
      model_.vertices.push_back(vector3(s, at));
      for (int i = 0; i < 3; ++i) next_word(s, at);
      return model_.colors.push_back(vector3(s, at));
    }
    if (count != 4) return;  // Assimp ignores the line (and numbers later vertices one less)
    std::size_t at = 1;
    const Vec3 v = vector3(s, at);
    for (int i = 0; i < 3; ++i) next_word(s, at);
    const float w = number(next_word(s, at));
    if (w == 0) throw Malformed("a homogeneous vertex with w = 0");
    model_.vertices.push_back({v.x / w, v.y / w, v.z / w});
  }

  void texture_coordinate(std::string_view s) {
    const std::size_t count = numeric_words(s, 2);
    if (count != 2 && count != 3)
      throw Malformed("a texture coordinate of " + std::to_string(count) +
                      " numbers (2 or 3 expected)");
    std::size_t at = 2;
    Vec3 t;
    t.x = number(next_word(s, at));
    t.y = number(next_word(s, at));
    if (count == 3) t.z = number(next_word(s, at));
    for (float* c : {&t.x, &t.y, &t.z})
      if (!std::isfinite(*c)) *c = 0;  // as Assimp: OBJ's default
    model_.uvs.push_back(t);
  }

  void face(std::string_view s, Prim prim);
  void add_face(Prim prim, bool has_normal);
  void use_material(std::string_view s);
  void material_library(std::string_view s);
  void group(std::string_view s);
  void object(std::string_view s);
  void create_object(const std::string& name);
  void create_mesh(const std::string& name);

  std::string path_;
  bool companions_;
  std::uint32_t max_corners_;
  FileAccesses* accessed_;
  Model model_;
  bool in_cstype_ = false;
  std::array<std::vector<std::uint32_t>, 3> corner_;  // the face being read: v, vt, vn indices
};

// getFace: indices as atoi reads them, the cursor moving by the value's digits (and sign), '/'
// moving to the next field, a space back to the first; negative indices count back from the
// vertices so far. Out-of-range indices are refused once the whole file is read.
void ObjParser::face(std::string_view s, Prim prim) {
  for (auto& list : corner_) list.clear();
  const bool has_uvs = !model_.uvs.empty(), has_normals = !model_.normals.empty();
  const std::array<std::int64_t, 3> sizes{std::int64_t(std::uint32_t(model_.vertices.size())),
                                          std::int64_t(std::uint32_t(model_.uvs.size())),
                                          std::int64_t(std::uint32_t(model_.normals.size()))};
  bool has_normal = false;
  int field = 0;
  for (std::size_t at = after_keyword(s); at < s.size();) {
    std::size_t step = 1;
    if (s[at] == '/') {
      ++field;
    } else if (is_space(s[at])) {
      field = 0;
    } else {
      const int value = c_atoi(s, at);
      for (int rest = value; (rest /= 10) != 0;) ++step;
      if (value < 0) ++step;
      if (field == 1 && !has_uvs && has_normals) field = 2;
      if (value == 0)
        throw Malformed("face index '" + printable(first_word(s.substr(at))) +
                        "' is not a nonzero integer");
      if (field >= 3) break;  // Assimp read on past the line's end here
      const std::int64_t index = value > 0 ? value - 1 : std::int32_t(sizes[field] + value);
      corner_[field].push_back(std::uint32_t(index));
      has_normal |= field == 2;
      if (prim == Prim::polygon && corner_[0].size() > max_corners_)
        throw Malformed("a face with more than " + std::to_string(max_corners_) +
                        " corners (raise it with --max-face-vertices)");
    }
    at += step;
  }
  if (!corner_[0].empty()) add_face(prim, has_normal);  // an empty face is ignored
}

void ObjParser::add_face(Prim prim, bool has_normal) {
  if (model_.current_object < 0) create_object("defaultobject");
  if (model_.current_mesh < 0) create_mesh("defaultobject");
  ObjMesh& mesh = model_.meshes[model_.current_mesh];
  mesh.faces.push_back({model_.indices.size(), std::uint32_t(corner_[0].size()),
                        std::uint32_t(corner_[1].size()), std::uint32_t(corner_[2].size()), prim});
  for (const auto& list : corner_)
    model_.indices.insert(model_.indices.end(), list.begin(), list.end());
  mesh.uv_corners += corner_[1].size();
  mesh.has_normals |= has_normal;
}

// getMaterialDesc: a material no .mtl defined is created with default properties; a new mesh
// starts when the current one has faces under another material.
void ObjParser::use_material(std::string_view s) {
  const std::string name(trim_end(s.substr(after_keyword(s))));
  if (name.empty()) return;
  if (model_.current_material >= 0 && model_.materials[model_.current_material].name == name)
    return;
  const auto found = model_.material_index.find(name);
  const std::uint32_t index =
      found != model_.material_index.end() ? found->second : add_material(model_, name);
  model_.current_material = int(index);
  if (model_.current_mesh < 0) {
    create_mesh(name);
  } else {
    const ObjMesh& mesh = model_.meshes[model_.current_mesh];
    if (mesh.material != kNoMaterial && mesh.material != index && !mesh.faces.empty())
      create_mesh(name);
  }
  model_.meshes[model_.current_mesh].material = index;
}

// getMaterialLib: the name (the rest of the line, spaces kept) in the OBJ's folder, else the
// OBJ's own name with .mtl. Without companions nothing is opened (Assimp, reading memory,
// looked in the working directory, then read the OBJ itself as the .mtl).
void ObjParser::material_library(std::string_view s) {
  const std::string name(s.substr(after_keyword(s)));
  if (name.empty() || !companions_) return;
  const std::size_t slash = path_.find_last_of("\\/");
  const std::string folder = slash == std::string::npos ? std::string() : path_.substr(0, slash);
  CompanionFiles files(path_, accessed_);
  auto text = files.open(folder.empty() ? name : folder + '/' + name);
  std::string mtl_path = folder.empty() ? name : folder + '/' + name;
  if (!text) {
    mtl_path = path_.substr(0, path_.size() - std::min<std::size_t>(3, path_.size())) + "mtl";
    text = files.open(mtl_path);
  }
  if (!text) return;
  std::string_view body(*text);
  if (body.substr(0, 3) == "\xEF\xBB\xBF") body.remove_prefix(3);  // as Assimp's ConvertToUTF8
  try {
    MtlReader(model_).read(body);
  } catch (const Malformed& e) {
    throw Malformed(std::string(e.what()) + " in " + printable(mtl_path));
  }
}

// getGroupName: the rest of the line; a new object whenever the name changes.
void ObjParser::group(std::string_view s) {
  const std::string name(s.substr(after_keyword(s)));
  if (name == model_.active_group) return;
  create_object(name);
  model_.active_group = name;
}

// getObjectName: the first word; an object of that name again becomes current (its mesh not).
void ObjParser::object(std::string_view s) {
  std::size_t at = after_keyword(s);
  const std::string name(first_word(s.substr(at)));
  if (name.empty()) return;
  if (const auto found = model_.object_index.find(name); found != model_.object_index.end()) {
    model_.current_object = int(found->second);
    return;
  }
  create_object(name);
}

void ObjParser::create_object(const std::string& name) {
  model_.objects.push_back({name, {}});
  model_.current_object = int(model_.objects.size() - 1);
  model_.object_index.emplace(name, std::uint32_t(model_.current_object));  // the first keeps it
  create_mesh(name);
  if (model_.current_material >= 0)
    model_.meshes[model_.current_mesh].material = std::uint32_t(model_.current_material);
}

// A mesh belongs to the current object; one made before any object (a `usemtl` first) belongs
// to none and is never output, as in Assimp.
void ObjParser::create_mesh(const std::string& name) {
  model_.meshes.push_back({name, {}, kNoMaterial, false, 0});
  model_.current_mesh = int(model_.meshes.size() - 1);
  if (model_.current_object >= 0)
    model_.objects[model_.current_object].meshes.push_back(std::uint32_t(model_.current_mesh));
}

// ---------------------------------------------------------------------------------------------
// A mesh as ObjFileImporter::createVertexArray laid it out: a vertex per corner (a line's inner
// corners twice), faces of 1 (points), 2 (line segments) or more indices.

struct CornerMesh {
  std::vector<Vec3> positions, normals, uvs;
  std::vector<std::array<float, 4>> colors;
  std::vector<std::uint32_t> indices;  // every face's, one after another
  std::vector<std::uint32_t> sizes;    // per face
  bool has_polygons = false;           // a face of more than 3 corners: triangulated
};

// Copies a line's inner corner to the next slot, the segment that ends there ending at the copy.
void duplicate_corner(CornerMesh& out, std::uint64_t slot, bool face_normals) {
  if (slot + 1 >= out.positions.size()) throw Malformed("a line of one vertex");
  out.positions[slot + 1] = out.positions[slot];
  if (face_normals && !out.normals.empty()) out.normals[slot + 1] = out.normals[slot];
  if (!out.uvs.empty()) out.uvs[slot + 1] = out.uvs[slot];
}

void add_corner(const Model& model, const Face& f, std::uint32_t i, std::uint64_t slot,
                CornerMesh& out, std::array<bool, 2>& ok) {
  const std::uint32_t* v = &model.indices[f.first];
  const std::uint32_t *t = v + f.nv, *n = t + f.nt;
  if (v[i] >= model.vertices.size())
    throw Malformed("a face names a vertex beyond the " + std::to_string(model.vertices.size()) +
                    " in the file");
  if (slot >= out.positions.size()) throw Malformed("a line of one vertex");
  out.positions[slot] = model.vertices[v[i]];
  if (ok[0] && !model.normals.empty() && i < f.nn) {
    if (n[i] >= model.normals.size())
      ok[0] = false;  // Assimp then dropped the mesh's normals, not the file
    else
      out.normals[slot] = model.normals[n[i]];
  }
  if (v[i] < model.colors.size()) {
    const Vec3& c = model.colors[v[i]];
    out.colors[slot] = {c.x, c.y, c.z, 1.0f};
  }
  if (ok[1] && !model.uvs.empty() && i < f.nt) {
    if (t[i] >= model.uvs.size())
      ok[1] = false;
    else
      out.uvs[slot] = model.uvs[t[i]];
  }
}

CornerMesh corner_mesh(const Model& model, const ObjMesh& mesh) {
  std::uint64_t slots = 0;
  for (const Face& f : mesh.faces)
    slots += f.prim == Prim::line ? 2 * std::uint64_t(f.nv - 1) : f.nv;
  if (slots == 0) throw Malformed("mesh '" + printable(mesh.name) + "' has no vertices");
  if (slots > 0x7fffffff) throw Malformed("mesh '" + printable(mesh.name) + "' is too large");
  CornerMesh out;
  out.positions.resize(slots);
  if (!model.normals.empty() && mesh.has_normals) out.normals.resize(slots);
  if (!model.uvs.empty() && mesh.uv_corners > 0) out.uvs.resize(slots);
  if (!model.colors.empty()) out.colors.resize(slots, {0, 0, 0, 0});
  out.indices.reserve(slots);
  std::array<bool, 2> ok{true, true};  // normals, texture coordinates
  std::uint64_t slot = 0;
  for (const Face& f : mesh.faces) {
    const std::size_t base = out.indices.size();
    if (f.prim == Prim::line && f.nv > 1) out.indices.resize(base + 2 * std::size_t(f.nv - 1));
    for (std::uint32_t i = 0; i < f.nv; ++i, ++slot) {
      add_corner(model, f, i, slot, out, ok);
      if (f.prim == Prim::point) {
        out.indices.push_back(std::uint32_t(slot));
        out.sizes.push_back(1);
      } else if (f.prim == Prim::polygon) {
        out.indices.push_back(std::uint32_t(slot));
      } else {
        const bool last = i + 1 == f.nv;
        if (!last) out.indices[base + 2 * i] = std::uint32_t(slot);
        if (i > 0 && !last) duplicate_corner(out, slot++, f.nn > 0);
        if (i > 0) out.indices[base + 2 * (i - 1) + 1] = std::uint32_t(slot);
      }
    }
    if (f.prim == Prim::polygon) out.sizes.push_back(f.nv);
    if (f.prim == Prim::polygon) out.has_polygons |= f.nv > 3;
    if (f.prim == Prim::line)
      for (std::uint32_t k = 1; k < f.nv; ++k) out.sizes.push_back(2);
  }
  if (!ok[0]) out.normals.clear();
  if (!ok[1]) out.uvs.clear();
  return out;
}

// ---------------------------------------------------------------------------------------------
// TriangulateProcess, float for float

using Tri = std::array<std::uint32_t, 3>;

struct Vec2 {
  float x, y;
  bool operator!=(const Vec2& o) const { return x != o.x || y != o.y; }
};

Vec3 sub(const Vec3& a, const Vec3& b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
float dot(const Vec3& a, const Vec3& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
// aiVector3D::Normalize: divided by its length (recomputed), left alone when zero.
Vec3 normalized(Vec3 v) {
  if (std::sqrt(dot(v, v)) == 0) return v;
  const float inverse = 1.0f / std::sqrt(dot(v, v));
  return {v.x * inverse, v.y * inverse, v.z * inverse};
}

// The quad's concave corner (the first whose two angles to the diagonal pass pi), else 0.
unsigned quad_start(const CornerMesh& m, const std::uint32_t* idx) {
  for (unsigned i = 0; i < 4; ++i) {
    const Vec3& v = m.positions[idx[i]];
    const Vec3 left = normalized(sub(m.positions[idx[(i + 3) % 4]], v));
    const Vec3 diag = normalized(sub(m.positions[idx[(i + 2) % 4]], v));
    const Vec3 right = normalized(sub(m.positions[idx[(i + 1) % 4]], v));
    const float angle = std::acos(dot(left, diag)) + std::acos(dot(right, diag));
    if (angle > 3.1415926538f) return i;
  }
  return 0;
}

double area2d(const Vec2& v1, const Vec2& v2, const Vec2& v3) {
  return 0.5 * (v1.x * (double(v3.y) - v2.y) + v2.x * (double(v1.y) - v3.y) +
                v3.x * (double(v2.y) - v1.y));
}

bool point_in_triangle(const Vec2& p0, const Vec2& p1, const Vec2& p2, const Vec2& pp) {
  const Vec2 v0{p1.x - p0.x, p1.y - p0.y}, v1{p2.x - p0.x, p2.y - p0.y},
      v2{pp.x - p0.x, pp.y - p0.y};
  auto dot2 = [](const Vec2& a, const Vec2& b) { return double(a.x * b.x + a.y * b.y); };
  const double d00 = dot2(v0, v0), d11 = dot2(v1, v1), d01 = dot2(v0, v1), d02 = dot2(v0, v2),
               d12 = dot2(v1, v2);
  const double denominator = d00 * d11 - d01 * d01;
  if (denominator == 0.0) return false;
  const double inverse = 1.0 / denominator;
  const double u = (d11 * d02 - d01 * d12) * inverse, v = (d00 * d12 - d01 * d02) * inverse;
  return u > 0 && v > 0 && u + v < 1;
}

// The polygon projected on the plane its Newell normal is most nearly along, in the winding
// that keeps it counter-clockwise.
std::vector<Vec2> project(const CornerMesh& m, const std::uint32_t* idx, int n) {
  std::vector<Vec3> p(std::size_t(n) + 2);
  for (int i = 0; i < n; ++i) p[i] = m.positions[idx[i]];
  p[n] = p[0];
  p[n + 1] = p[1];
  float xy = 0, yz = 0, zx = 0;
  for (int i = 0; i < n; ++i) {
    xy += p[i + 1].x * (p[i + 2].y - p[i].y);
    yz += p[i + 1].y * (p[i + 2].z - p[i].z);
    zx += p[i + 1].z * (p[i + 2].x - p[i].x);
  }
  const Vec3 normal{yz, zx, xy};
  const float ax = std::fabs(normal.x), ay = std::fabs(normal.y), az = std::fabs(normal.z);
  int a = 0, b = 1;
  float facing = normal.z;
  if (ax > ay) {
    if (ax > az) a = 1, b = 2, facing = normal.x;
  } else if (ay > az) {
    a = 2, b = 0, facing = normal.y;
  }
  if (facing < 0.f) std::swap(a, b);
  std::vector<Vec2> out(static_cast<std::size_t>(n));
  auto axis = [](const Vec3& v, int k) { return k == 0 ? v.x : k == 1 ? v.y : v.z; };
  for (int i = 0; i < n; ++i) out[i] = {axis(p[i], a), axis(p[i], b)};
  return out;
}

// Ear clipping as TriangulateProcess did it: an ear is a convex corner whose triangle holds no
// other corner (corners at the same 2D point as its own excepted); after two passes without
// one the rest of the polygon is dropped. Triangles in the polygon's local indices.
void clip_ears(const std::vector<Vec2>& v, std::vector<Tri>& out) {
  const int max = int(v.size());
  std::vector<char> done(v.size(), 0);
  int num = max, ear = 0, prev = num - 1, next = 0;
  while (num > 3) {
    int passes = 0;
    for (ear = next;; prev = ear, ear = next) {
      for (next = ear + 1; done[(next >= max ? next = 0 : next)]; ++next) {
      }
      if (next < ear && ++passes == 2) break;
      const Vec2 &p0 = v[prev], &p1 = v[ear], &p2 = v[next];
      if (area2d(p0, p1, p2) > 0) continue;  // a reflex corner
      int k = 0;
      for (; k < max; ++k)
        if (v[k] != p1 && v[k] != p2 && v[k] != p0 && point_in_triangle(p0, p1, p2, v[k])) break;
      if (k == max) break;
    }
    if (passes == 2) return;  // no ear: not a simple polygon
    out.push_back({std::uint32_t(prev), std::uint32_t(ear), std::uint32_t(next)});
    done[ear] = 1;
    --num;
  }
  Tri last{};
  for (int k = 0, found = 0; found < 3; ++k)
    if (!done[k]) last[found++] = std::uint32_t(k);
  out.push_back(last);
}

// The triangles of a mesh in face order, every index a face uses marked, and whether it has a
// line segment (which makes a mesh without triangles a wireframe, not a point cloud).
struct Triangulated {
  std::vector<Tri> triangles;
  std::vector<std::uint8_t> used;
  bool has_lines = false;
};

// TriangulateProcess's n-gon encoding: a triangle starting where the previous one did is
// rotated to start at its last corner (quads: both turned to fan from the opposite corner).
class NgonEncoder {
 public:
  void triangle(Tri& t) {
    if (t[0] == last_) t = {t[2], t[0], t[1]};
    last_ = t[0];
  }
  void quad(Tri& a, Tri& b) {
    if (a[0] == last_) {
      a = {a[2], a[0], a[1]};
      b = {b[1], b[2], b[0]};
    }
    last_ = a[0];
  }

 private:
  std::uint32_t last_ = ~0u;
};

void triangulate_face(const CornerMesh& m, const std::uint32_t* idx, std::uint32_t n,
                      NgonEncoder& encoder, std::vector<Tri>& out) {
  if (n == 3) {
    Tri t{idx[0], idx[1], idx[2]};
    if (m.has_polygons) encoder.triangle(t);
    out.push_back(t);
  } else if (n == 4) {
    const unsigned s = quad_start(m, idx);
    Tri a{idx[s], idx[(s + 1) % 4], idx[(s + 2) % 4]},
        b{idx[s], idx[(s + 2) % 4], idx[(s + 3) % 4]};
    encoder.quad(a, b);
    out.push_back(a);
    out.push_back(b);
  } else if (n > 4) {
    const std::size_t first = out.size();
    clip_ears(project(m, idx, int(n)), out);
    for (std::size_t k = first; k < out.size(); ++k) {
      for (auto& corner : out[k]) corner = idx[corner];
      encoder.triangle(out[k]);
    }
  }
}

Triangulated triangulate(const CornerMesh& m) {
  Triangulated out;
  out.used.assign(m.positions.size(), 0);
  NgonEncoder encoder;
  const std::uint32_t* idx = m.indices.data();
  for (const std::uint32_t n : m.sizes) {
    out.has_lines |= n == 2;
    for (std::uint32_t k = 0; n < 3 && k < n; ++k) out.used[idx[k]] = 1;
    triangulate_face(m, idx, n, encoder, out.triangles);
    idx += n;
  }
  // Corners of a polygon left unclipped are used by no face, so JoinIdenticalVertices drops them.
  for (const Tri& t : out.triangles)
    for (const std::uint32_t v : t) out.used[v] = 1;
  return out;
}

// ---------------------------------------------------------------------------------------------
// JoinIdenticalVertices and Kiln's conversion

// A position's bits, -0 as +0 (equal floats hash alike in Assimp's table).
std::array<std::uint32_t, 3> position_key(const Vec3& p) {
  auto bits = [](float f) { return f == 0 ? 0u : std::bit_cast<std::uint32_t>(f); };
  return {bits(p.x), bits(p.y), bits(p.z)};
}

// Assimp's test once positions are equal: normals and texture coordinates each within 1e-5 (a
// NaN difference passes, as there); absent ones are zero on both sides.
bool joinable(const CornerMesh& m, std::uint32_t a, std::uint32_t b) {
  constexpr float kEpsilon2 = 1e-5f * 1e-5f;
  auto far = [&](const std::vector<Vec3>& values) {
    if (values.empty()) return false;
    const Vec3 d = sub(values[a], values[b]);
    return dot(d, d) > kEpsilon2;
  };
  return !far(m.normals) && !far(m.uvs);
}

// For every used vertex, the vertex it becomes: in vertex order, a vertex joins the newest
// earlier kept vertex at its position that it is joinable with (the one Assimp's hash map found
// first), else is kept. Kept vertices are chained per position from a hash table; only the
// newest kKeptScanned are tried, so that a hostile file cannot make this quadratic.
std::vector<std::uint32_t> join_targets(const CornerMesh& m,
                                        const std::vector<std::uint8_t>& used) {
  constexpr std::size_t kKeptScanned = 1024;
  constexpr std::uint32_t kNone = ~0u;
  std::vector<std::uint32_t> first(m.positions.size(), 0), older(m.positions.size(), kNone);
  std::size_t size = 16;
  while (size < 2 * m.positions.size()) size *= 2;
  std::vector<std::uint32_t> heads(size, kNone);  // newest kept vertex per position
  for (std::uint32_t v = 0; v < used.size(); ++v) {
    if (used[v] == 0) continue;
    const auto key = position_key(m.positions[v]);
    std::size_t slot =
        (key[0] * 0x9E3779B1u ^ key[1] * 0x85EBCA77u ^ key[2] * 0xC2B2AE3Du) & (size - 1);
    while (heads[slot] != kNone && position_key(m.positions[heads[slot]]) != key)
      slot = (slot + 1) & (size - 1);
    first[v] = v;
    std::size_t tried = 0;
    for (std::uint32_t k = heads[slot]; k != kNone && tried++ < kKeptScanned; k = older[k])
      if (joinable(m, v, k)) {
        first[v] = k;
        break;
      }
    if (first[v] != v) continue;
    older[v] = heads[slot];
    heads[slot] = v;
  }
  return first;
}

std::uint32_t color_of(const std::array<float, 4>& c, const std::array<float, 4>& tint) {
  for (const float channel : c)
    if (!std::isfinite(channel)) throw Malformed("a vertex colour holds a non-finite value");
  return pack_rgba8(double(c[0]) * tint[0], double(c[1]) * tint[1], double(c[2]) * tint[2],
                    double(c[3]) * tint[3]);
}

// The joined vertices (numbered in order of first use) and triangles, with colours as Kiln's
// mesh_colors made them: vertex colour times base colour, or the base colour alone.
ImportedMesh joined_mesh(const CornerMesh& m, const Triangulated& t,
                         const std::optional<std::array<float, 4>>& base) {
  if (base && !std::all_of(base->begin(), base->end(), [](float c) { return std::isfinite(c); }))
    throw Malformed("a material's base colour holds a non-finite value");
  const std::vector<std::uint32_t> first = join_targets(m, t.used);
  std::vector<std::uint32_t> number(m.positions.size(), 0);
  ImportedMesh out;
  const std::array<float, 4> tint = base.value_or(std::array{1.0f, 1.0f, 1.0f, 1.0f});
  for (std::uint32_t v = 0; v < m.positions.size(); ++v) {
    if (t.used[v] == 0) continue;
    if (first[v] != v) {
      number[v] = number[first[v]];
      continue;
    }
    number[v] = std::uint32_t(out.positions.size());
    const Vec3& p = m.positions[v];
    out.positions.push_back({p.x, p.y, p.z});
    if (!m.normals.empty()) out.normals.push_back({m.normals[v].x, m.normals[v].y, m.normals[v].z});
    if (!m.colors.empty()) out.colors.push_back(color_of(m.colors[v], tint));
  }
  if (m.colors.empty() && base)
    out.colors.assign(out.positions.size(), pack_rgba8(tint[0], tint[1], tint[2], tint[3]));
  out.triangles.reserve(t.triangles.size());
  for (const Tri& tri : t.triangles)
    out.triangles.push_back({{number[tri[0]], number[tri[1]], number[tri[2]]}});
  out.point_cloud = out.triangles.empty() && !t.has_lines;
  return out;
}

// A file of vertices and no object, group or face: all its vertices, as one point cloud named
// after the file (Assimp's root node; reading memory it was named "$$$___magic___$$$.obj").
std::vector<ImportedMesh> point_cloud(const Model& model, const std::string& path) {
  std::vector<ImportedMesh> meshes;
  const std::size_t n = model.vertices.size();
  if (n == 0) return meshes;
  ImportedMesh& out = meshes.emplace_back();
  out.name = ai_name(path.substr(path.find_last_of("\\/") + 1));
  for (const Vec3& p : model.vertices) out.positions.push_back({p.x, p.y, p.z});
  if (!model.normals.empty()) {
    if (model.normals.size() < n) throw Malformed("fewer normals than vertices in a point cloud");
    for (std::size_t v = 0; v < n; ++v)
      out.normals.push_back({model.normals[v].x, model.normals[v].y, model.normals[v].z});
  }
  if (!model.colors.empty()) {
    if (model.colors.size() < n) throw Malformed("fewer colours than vertices in a point cloud");
    for (std::size_t v = 0; v < n; ++v) {
      const Vec3& c = model.colors[v];
      out.colors.push_back(color_of({c.x, c.y, c.z, 1.0f}, {1.0f, 1.0f, 1.0f, 1.0f}));
    }
  }
  out.point_cloud = true;
  return meshes;
}

// Objects in order, each one's meshes with faces in order; a mesh without triangles that is
// not a point cloud (lines only) is dropped, as Kiln's Assimp walk dropped it.
std::vector<ImportedMesh> meshes_of(const Model& model) {
  std::vector<ImportedMesh> meshes;
  for (const ObjObject& object : model.objects)
    for (const std::uint32_t id : object.meshes) {
      const ObjMesh& mesh = model.meshes[id];
      if (mesh.faces.empty()) continue;
      const CornerMesh corners = corner_mesh(model, mesh);
      ImportedMesh out =
          joined_mesh(corners, triangulate(corners), base_color(model, mesh.material));
      if (out.triangles.empty() && !out.point_cloud) continue;
      out.name = ai_name(mesh.name);
      if (out.name.empty()) out.name = ai_name(object.name);
      meshes.push_back(std::move(out));
    }
  return meshes;
}

}  // namespace

std::vector<ImportedMesh> import_obj(const std::string& path, std::span<const std::byte> bytes,
                                     bool companions, const ImportLimits& limits,
                                     FileAccesses* accessed) {
  check_obj_faces(path, bytes, limits.max_face_vertices);
  if (bytes.size() < 16)
    throw ImportError(path + ": " + std::to_string(bytes.size()) +
                      " bytes, too small for an OBJ file (Assimp read none under 16)");
  ObjParser parser(path, companions, limits.max_face_vertices, accessed);
  parser.read({reinterpret_cast<const char*>(bytes.data()), bytes.size()});
  try {
    const Model& model = parser.model();
    return model.objects.empty() ? point_cloud(model, path) : meshes_of(model);
  } catch (const Malformed& e) {
    throw ImportError(path + ": " + e.what());
  }
}

}  // namespace kiln
