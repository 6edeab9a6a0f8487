// Names of the input kinds, and which input offers what a structure consumes.
#include "kiln/runtime/input_kind.hpp"

namespace kiln {

std::string_view input_kind_name(InputKind kind) {
  switch (kind) {
    case InputKind::kTriangles:
      return "triangle scene";
    case InputKind::kPoint3:
      return "3D point set";
    case InputKind::kPolygons2:
      return "2D polygon layer";
    case InputKind::kPoint2:
      return "2D point table";
    case InputKind::kEvents:
      return "event table";
  }
  return "?";
}

bool input_provides(InputKind input, InputKind consumed) {
  return input == consumed || (input == InputKind::kTriangles && consumed == InputKind::kPoint3);
}

}  // namespace kiln
