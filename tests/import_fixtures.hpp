// Small meshes whose import reads more than one file (an OBJ and its .mtl, a glTF and its
// .bin), for the depfile and build-cache tests, and the check of an import's refusal.
#pragma once

#include <filesystem>
#include <span>
#include <string>

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

}  // namespace kiln::test
