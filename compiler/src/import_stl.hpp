// Kiln's own STL reader: binary and ASCII (several solids), read as Assimp 5.2.5 read them; see
// import_stl.cpp for the rules.
#pragma once

#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include "kiln/compiler/scene.hpp"

namespace kiln {

// Whether `bytes` are a binary STL by Assimp's test: 84 + 50 * (the count at byte 80) is the size,
// whatever the header says (exporters often start a binary header with "solid").
bool is_binary_stl(std::span<const std::byte> bytes);

// A binary STL gives one mesh named ""; an ASCII one a mesh per solid that has facets, named as
// the solid. `path` names the file in errors. Throws ImportError with one line:
// "path: what is wrong" (ASCII: "path: line N: what is wrong").
std::vector<ImportedMesh> import_stl(const std::string& path, std::span<const std::byte> bytes);

}  // namespace kiln
