// Kiln's own PLY reader: ASCII and binary (little and big endian) 1.0, `face` polygons and
// `tristrips` with -1 restarts; see import_ply.cpp for the rules.
#pragma once

#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include "kiln/compiler/scene.hpp"

namespace kiln {

// One mesh named "" (a point cloud when the file has vertices but no faces). `path` names the
// file in errors. Throws ImportError with one line: "path: what is wrong (element, entry, line)".
std::vector<ImportedMesh> import_ply(const std::string& path, std::span<const std::byte> bytes);

}  // namespace kiln
