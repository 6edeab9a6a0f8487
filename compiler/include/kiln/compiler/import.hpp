// Mesh import: Kiln's own readers for PLY (strips included), STL (binary and ASCII; Assimp 5.2.5
// leaks on malformed ASCII STL) and OBJ (with its .mtl base colours, giving exactly what Assimp
// 5.2.5 gave, in 0.01 ms for a tiny file where Assimp took 0.7 ms); Assimp for FBX, DAE, 3DS,
// OFF, 3MF...; tinygltf (+ Draco) for glTF 2.0; Draco for raw .drc bitstreams. A trailing .zst
// on any input is inflated first.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
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

/// Limits that refuse a hostile input early, in one line, before it exhausts memory or time.
/// Each is stated in docs/FUZZING.md and overridable from `kiln build`.
struct ImportLimits {
  /// The most a `.zst` input may inflate to (`--max-inflated-size`). A zstd frame that declares
  /// more is refused before inflating; a streamed one as soon as it passes the limit, so memory
  /// stays within it.
  std::uint64_t max_inflated_bytes = std::uint64_t{4} << 30;
  /// The most corners an OBJ polygon may have (`--max-face-vertices`): Assimp triangulates a
  /// polygon in worse than quadratic time (a 30,000-gon takes 6 s), so a face of 10^8 corners
  /// would never finish.
  std::uint32_t max_face_vertices = 4096;
};

/// A file's bytes as an importer sees them: read whole and, for a trailing `.zst`, inflated
/// within `limits` (`inner_name` is then the path without `.zst`). What the 2D and event-table
/// readers start from.
struct InputBytes {
  SourceFile source;       ///< the path as given, the stored size and XXH3
  std::string inner_name;  ///< names the bytes in errors and picks the reader by extension
  std::span<const std::byte> bytes;
  std::shared_ptr<const void> owner;  ///< keeps `bytes` alive
};
/// Throws ImportError: no such file, not readable, empty, bad zstd, over the inflate limit.
InputBytes read_input_bytes(const std::string& path, const ImportLimits& limits = {});

// Reads and imports one file; its `accessed` lists `path` and every companion file read
// (normalized). Throws ImportError.
ImportedFile import_file(const std::string& path, const ImportLimits& limits = {});

// The same over a file's bytes already in memory (`path` names them in errors and picks the
// importer by extension; a trailing .zst inflates them). With `companions`, importers look for
// companion files beside `path` (an OBJ's .mtl, a glTF's buffers); without, Assimp reads only
// `stored` (what the fuzzers use).
ImportedFile import_bytes(const std::string& path, std::span<const std::byte> stored,
                          const ImportLimits& limits, bool companions);

// Importers over bytes already in memory. `path` names the file in errors and locates companion
// files (a glTF's .bin buffers, an OBJ's .mtl); `extension` is lower-case with its dot. Every file
// they open, and every companion they look for in vain, is appended to `accessed` when given
// (as the library spelled it: import_file normalizes). With `bytes_are_file`, Assimp reads
// `path` itself, so it is recorded too. An OBJ polygon beyond `limits` is refused before Assimp
// sees it.
std::vector<ImportedMesh> import_with_assimp(const std::string& path,
                                             std::span<const std::byte> bytes,
                                             const std::string& extension, bool bytes_are_file,
                                             const ImportLimits& limits,
                                             FileAccesses* accessed = nullptr);
// Kiln's OBJ reader: the meshes, names, base colours (from the .mtl) and joined, triangulated
// vertices the Assimp path gave, in its order. With `companions` the .mtl is looked for beside
// `path` as Assimp looked for it; without, none is read. Errors: "path: what" or
// "path:LINE: what".
std::vector<ImportedMesh> import_obj(const std::string& path, std::span<const std::byte> bytes,
                                     bool companions, const ImportLimits& limits,
                                     FileAccesses* accessed = nullptr);
std::vector<ImportedMesh> import_gltf(const std::string& path, std::span<const std::byte> bytes,
                                      bool binary, FileAccesses* accessed = nullptr);
std::vector<ImportedMesh> import_draco(const std::string& path, std::span<const std::byte> bytes);

}  // namespace kiln
