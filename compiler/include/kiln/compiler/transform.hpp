// Affine node transforms, applied in double so instancing adds no error beyond the final
// rounding to float.
#pragma once

#include <array>

#include "kiln/formats/geometry.hpp"

namespace kiln {

using Matrix4 =
    std::array<double, 16>;  // column-major (glTF's order): element (r, c) = m[c * 4 + r]

inline constexpr Matrix4 kIdentity = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};

Matrix4 multiply(const Matrix4& a, const Matrix4& b);
double determinant3(const Matrix4& m);  // of the upper-left 3x3
using Double3 = std::array<double, 3>;
Double3 transform_point(const Matrix4& m, const format::Float3& p);
// Transforms a normal by the inverse transpose (cofactor matrix) and normalises it; a zero or
// non-finite result is returned unnormalised.
format::Float3 transform_normal(const Matrix4& m, const format::Float3& n);

}  // namespace kiln
