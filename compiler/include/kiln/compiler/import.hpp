// Mesh import: Kiln's own reader for PLY (strips included); Assimp for OBJ, STL, FBX, DAE, 3DS,
// OFF, 3MF...; tinygltf (+ Draco) for glTF 2.0; Draco for raw .drc bitstreams. A trailing .zst on
// any input is inflated first.
#pragma once

#include <cstddef>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "kiln/compiler/scene.hpp"

namespace kiln {

// A mesh file that cannot be imported. what() is one line: "path: reason".
class ImportError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Reads and imports one file; its `accessed` lists `path` and every companion file read
// (normalized). Throws ImportError.
ImportedFile import_file(const std::string& path);

// Importers over bytes already in memory. `path` names the file in errors and locates companion
// files (a glTF's .bin buffers, an OBJ's .mtl); `extension` is lower-case with its dot. Every file
// they open, and every companion they look for in vain, is appended to `accessed` when given
// (as the library spelled it: import_file normalizes). With `bytes_are_file`, Assimp reads
// `path` itself, so it is recorded too.
std::vector<ImportedMesh> import_with_assimp(const std::string& path,
                                             std::span<const std::byte> bytes,
                                             const std::string& extension, bool bytes_are_file,
                                             FileAccesses* accessed = nullptr);
std::vector<ImportedMesh> import_gltf(const std::string& path, std::span<const std::byte> bytes,
                                      bool binary, FileAccesses* accessed = nullptr);
std::vector<ImportedMesh> import_draco(const std::string& path, std::span<const std::byte> bytes);

}  // namespace kiln
