// Double-precision 3-vectors for camera set-up (kiln rays, kiln render): the maths runs in double
// and rounds once to float, so every generated ray is the same on every run and compiler.
#pragma once

#include <cmath>

#include "kiln/formats/geometry.hpp"

namespace kiln::vec3d {

struct Vec {
  double x = 0, y = 0, z = 0;
};
inline Vec operator+(Vec a, Vec b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z};
}
inline Vec operator-(Vec a, Vec b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
inline Vec operator*(Vec a, double s) {
  return {a.x * s, a.y * s, a.z * s};
}
inline double dot(Vec a, Vec b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
inline Vec cross(Vec a, Vec b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline Vec normalize(Vec a) {
  return a * (1.0 / std::sqrt(dot(a, a)));
}
inline Vec vec(const format::Float3& f) {
  return {f.x, f.y, f.z};
}
inline format::Float3 f3(Vec a) {
  return {float(a.x), float(a.y), float(a.z)};
}

}  // namespace kiln::vec3d
