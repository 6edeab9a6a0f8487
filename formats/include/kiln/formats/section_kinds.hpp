// Section kinds (FourCC) of the manifest and of the inputs. A structure's own section kinds live
// in its layout header (kiln/formats/<structure>.hpp).
#pragma once

#include <cstdint>
#include <string>

#include "kiln/formats/container.hpp"

namespace kiln::format {

inline constexpr std::uint32_t kSectionManifest = fourcc('M', 'A', 'N', 'I');   // FlatBuffer
inline constexpr std::uint32_t kSectionPositions = fourcc('V', 'P', 'O', 'S');  // Float3 per vertex
inline constexpr std::uint32_t kSectionNormals = fourcc('V', 'N', 'R', 'M');    // Float3 per vertex
inline constexpr std::uint32_t kSectionTriangles = fourcc('T', 'R', 'I', 'S');  // Triangle
inline constexpr std::uint32_t kSectionTriangleMesh = fourcc('T', 'M', 'S', 'H');  // uint32 mesh id

inline std::string fourcc_to_string(std::uint32_t kind) {
  std::string text;
  for (int i = 0; i < 4; ++i) {
    const auto c = char((kind >> (8 * i)) & 0xFF);
    text += (c >= 0x20 && c < 0x7F) ? c : '?';
  }
  return text;
}

}  // namespace kiln::format
