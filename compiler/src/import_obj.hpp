// Internals of Kiln's OBJ reader (import_obj, declared in kiln/compiler/import.hpp; the rules
// are in import_obj.cpp) that the Assimp path shares.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include "kiln/compiler/import.hpp"

namespace kiln {

// Refuses a polygon (an `f` line) with more corners than `limit`, in one pass over the text
// before anything is triangulated; shared by import_obj and the Assimp path.
void check_obj_faces(const std::string& path, std::span<const std::byte> bytes,
                     std::uint32_t limit);

}  // namespace kiln
