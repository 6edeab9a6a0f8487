// The kinds of input a blob is built from, and so what a structure may consume.
#pragma once

#include <cstdint>
#include <string_view>

namespace kiln {

enum class InputKind : std::uint8_t {
  kTriangles,  ///< a triangle scene (meshes)
  kPoints3,    ///< 3D points: a point cloud, or a triangle scene's vertices
  kPolygons2,  ///< a 2D polygon layer
  kPoints2,    ///< a 2D point table
  kEvents,     ///< an event table
};

/// "triangles", "3D points", ...: for messages.
std::string_view input_kind_name(InputKind kind);

/// Whether a blob built from `input` offers what a structure consuming `consumed` needs: a
/// triangle scene also offers its vertices as 3D points.
bool input_provides(InputKind input, InputKind consumed);

}  // namespace kiln
