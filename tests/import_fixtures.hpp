// Small meshes whose import reads more than one file (an OBJ and its .mtl, a glTF and its
// .bin), for the depfile and build-cache tests, and the check of an import's refusal.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "kiln/compiler/import.hpp"
#include "test_support.hpp"

namespace kiln::test {

// Runs `body`, expecting an ImportError whose one-line message contains `needle`.
template <class F>
void expect_import_error(F body, const std::string& needle) {
  try {
    body();
    ADD_FAILURE() << "no ImportError (wanted one mentioning '" << needle << "')";
  } catch (const ImportError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(needle), std::string::npos) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
}

// One red triangle in an OBJ whose colour lives in `mtl_name`.
inline void write_obj_with_mtl(const std::filesystem::path& dir, const std::string& mtl_name,
                               const char* kd) {
  write_text(dir / "mesh.obj",
             "mtllib " + mtl_name + "\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n");
  write_text(dir / mtl_name, std::string("newmtl red\nKd ") + kd + "\n");
}

// A one-triangle glTF whose positions live in the external buffer `bin_name` (36 bytes), and
// which names an external image (that a geometry importer has no reason to open).
inline void write_gltf_with_bin(const std::filesystem::path& dir, const std::string& bin_name,
                                float x) {
  const float positions[9] = {0, 0, 0, x, 0, 0, 0, 1, 0};
  write_file((dir / bin_name).string(), std::as_bytes(std::span(positions)));
  write_text(dir / "texture.png", "not really a PNG");
  write_text(dir / "mesh.gltf", R"({
  "asset": {"version": "2.0"},
  "scene": 0,
  "scenes": [{"nodes": [0]}],
  "nodes": [{"mesh": 0}],
  "meshes": [{"name": "tri", "primitives": [{"attributes": {"POSITION": 0}}]}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                 "min": [0, 0, 0], "max": [1, 1, 0]}],
  "bufferViews": [{"buffer": 0, "byteLength": 36}],
  "buffers": [{"uri": ")" + bin_name +
                                    R"(", "byteLength": 36}],
  "images": [{"uri": "texture.png"}]
})");
}

// The one-line ImportError that `bytes` give as the file `name` in a fresh folder, after the
// "path: " it must start with; "no error" when they import.
inline std::string import_refusal(const std::string& name, const std::vector<std::byte>& bytes) {
  TempDir dir;
  const std::string path = dir.file(name);
  write_file(path, bytes);
  try {
    import_file(path);
  } catch (const ImportError& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind(path + ": ", 0), 0u) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    return message.substr(path.size() + 2);
  }
  return "no error";
}

// A colour packed as ImportedMesh::colors holds it (RGBA8, red in the low byte).
inline std::uint32_t rgba(std::uint32_t r, std::uint32_t g, std::uint32_t b, std::uint32_t a) {
  return r | g << 8 | b << 16 | a << 24;
}

}  // namespace kiln::test

// Expects the refusal of `bytes` (through the test file's own `import_error`) to contain `needle`.
#define EXPECT_REFUSED(bytes, needle)                                       \
  do {                                                                      \
    const std::string reason = import_error(bytes);                         \
    EXPECT_NE(reason.find(needle), std::string::npos) << "got: " << reason; \
  } while (0)
