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

// The 2D inputs (docs/FORMAT.md, "2D inputs"). Offsets are uint64 arrays of count + 1 entries,
// starting at 0, non-decreasing, ending at the count of what they index.
inline constexpr std::uint32_t kSectionLayerVertices = fourcc('L', 'V', 'R', 'T');  // Double2
inline constexpr std::uint32_t kSectionLayerRings = fourcc('L', 'R', 'N', 'G');  // ring -> vertices
inline constexpr std::uint32_t kSectionLayerPolygons = fourcc('L', 'P', 'L', 'Y');  // -> rings
inline constexpr std::uint32_t kSectionLayerFeatures = fourcc('L', 'F', 'E', 'A');  // -> polygons
inline constexpr std::uint32_t kSectionPoints2 = fourcc('P', '2', 'X', 'Y');        // Double2
inline constexpr std::uint32_t kSectionPointFeatures = fourcc('P', '2', 'F', 'E');  // -> points
inline constexpr std::uint32_t kSectionStringOffsets = fourcc('S', 'T', 'R', 'O');  // uint64
inline constexpr std::uint32_t kSectionStringBytes = fourcc('S', 'T', 'R', 'B');    // UTF-8

/// Every section kind an input may own (structures list theirs in the runtime's registry).
inline constexpr std::uint32_t kInputSectionKinds[] = {
    kSectionPositions,     kSectionNormals,       kSectionTriangles,     kSectionTriangleMesh,
    kSectionLayerVertices, kSectionLayerRings,    kSectionLayerPolygons, kSectionLayerFeatures,
    kSectionPoints2,       kSectionPointFeatures, kSectionStringOffsets, kSectionStringBytes};

inline std::string fourcc_to_string(std::uint32_t kind) {
  std::string text;
  for (int i = 0; i < 4; ++i) {
    const auto c = char((kind >> (8 * i)) & 0xFF);
    text += (c >= 0x20 && c < 0x7F) ? c : '?';
  }
  return text;
}

}  // namespace kiln::format
