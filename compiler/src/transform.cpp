#include "kiln/compiler/transform.hpp"

#include <cmath>

namespace kiln {

Matrix4 multiply(const Matrix4& a, const Matrix4& b) {
  Matrix4 r{};
  for (int c = 0; c < 4; ++c)
    for (int row = 0; row < 4; ++row) {
      double sum = 0;
      for (int k = 0; k < 4; ++k) sum += a[k * 4 + row] * b[c * 4 + k];
      r[c * 4 + row] = sum;
    }
  return r;
}

double determinant3(const Matrix4& m) {
  return m[0] * (m[5] * m[10] - m[9] * m[6]) - m[4] * (m[1] * m[10] - m[9] * m[2]) +
         m[8] * (m[1] * m[6] - m[5] * m[2]);
}

Double3 transform_point(const Matrix4& m, const format::Float3& p) {
  const double x = p.x, y = p.y, z = p.z;
  return {m[0] * x + m[4] * y + m[8] * z + m[12], m[1] * x + m[5] * y + m[9] * z + m[13],
          m[2] * x + m[6] * y + m[10] * z + m[14]};
}

format::Float3 transform_normal(const Matrix4& m, const format::Float3& n) {
  // Cofactor matrix of the upper 3x3 = det * inverse-transpose; the scale is normalised away.
  auto a = [&](int row, int col) { return m[col * 4 + row]; };
  const double in[3] = {n.x, n.y, n.z};
  double out[3] = {0, 0, 0};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      const int r1 = (r + 1) % 3, r2 = (r + 2) % 3, c1 = (c + 1) % 3, c2 = (c + 2) % 3;
      out[r] += (a(r1, c1) * a(r2, c2) - a(r1, c2) * a(r2, c1)) * in[c];
    }
  const double length = std::sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2]);
  if (length > 0 && std::isfinite(length))
    for (double& v : out) v /= length;
  return {float(out[0]), float(out[1]), float(out[2])};
}

}  // namespace kiln
