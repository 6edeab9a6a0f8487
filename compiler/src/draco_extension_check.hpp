#pragma once

#include <cstddef>
#include <span>
#include <string>
#include <string_view>

#include "kiln/compiler/file_accesses.hpp"

namespace kiln {

// tinygltf 2.7.0 decodes KHR_draco_mesh_compression while parsing, trusting every index in the
// extension (buffer views, accessors, Draco attribute ids). This checks those references on
// the raw JSON first, so a hostile file is an ImportError instead of an out-of-range read.
// `json` is the glTF JSON; `glb_bin` the GLB's BIN chunk (empty for .gltf). External buffers it
// reads are appended to `accessed` when given.
void check_draco_extensions(const std::string& path, std::string_view json,
                            std::span<const std::byte> glb_bin, const std::string& base_dir,
                            FileAccesses* accessed = nullptr);

// The JSON and BIN chunks of a GLB container. Throws ImportError when malformed.
struct GlbChunks {
  std::string_view json;
  std::span<const std::byte> bin;
};
GlbChunks split_glb(const std::string& path, std::span<const std::byte> bytes);

}  // namespace kiln
