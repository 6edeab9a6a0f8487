// The kinds of input a blob is built from, and so what a structure may consume.
#pragma once

#include <cstdint>
#include <string_view>

namespace kiln {

enum class InputKind : std::uint8_t {
  kTriangles,  ///< a triangle scene (meshes)
  kPoint3,     ///< a 3D point set: a point cloud, or a triangle scene's vertices
  kPolygons2,  ///< a 2D polygon layer
  kPoint2,     ///< a 2D point table
  kEvents,     ///< an event table
};

/// "triangle scene", "3D point set", ...: for messages.
std::string_view input_kind_name(InputKind kind);

/// Whether a blob built from `input` offers what a structure consuming `consumed` needs: a
/// triangle scene also offers its vertices as a 3D point set.
bool input_provides(InputKind input, InputKind consumed);

}  // namespace kiln
