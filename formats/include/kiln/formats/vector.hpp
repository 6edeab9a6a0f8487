// The one family of 3-vectors and axis-aligned boxes every layer uses: float for what is stored
// and built, double for exact predicates and camera maths.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>

namespace kiln::format {

/// A point or direction in float; the element layout of stored positions.
struct Float3 {
  float x, y, z;
};
static_assert(sizeof(Float3) == 12);
static_assert(offsetof(Float3, z) == 8);

/// A point or direction in double.
struct Double3 {
  double x, y, z;
};

/// Component `axis` (0 = x, 1 = y, 2 = z) of a vector.
constexpr float& at(Float3& v, int axis) {
  return axis == 0 ? v.x : axis == 1 ? v.y : v.z;
}
constexpr float at(const Float3& v, int axis) {
  return axis == 0 ? v.x : axis == 1 ? v.y : v.z;
}
constexpr double& at(Double3& v, int axis) {
  return axis == 0 ? v.x : axis == 1 ? v.y : v.z;
}
constexpr double at(const Double3& v, int axis) {
  return axis == 0 ? v.x : axis == 1 ? v.y : v.z;
}

constexpr Double3 to_d(const Float3& p) {
  return {p.x, p.y, p.z};
}
constexpr Float3 to_f(const Double3& p) {
  return {float(p.x), float(p.y), float(p.z)};
}

constexpr Double3 operator-(Double3 a, Double3 b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
constexpr Double3 operator+(Double3 a, Double3 b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z};
}
constexpr Double3 operator*(Double3 a, double s) {
  return {a.x * s, a.y * s, a.z * s};
}
constexpr double dot(Double3 a, Double3 b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
constexpr Double3 cross(Double3 a, Double3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
/// `a` scaled to unit length (NaN for the zero vector).
inline Double3 normalize(Double3 a) {
  return a * (1.0 / std::sqrt(dot(a, a)));
}

/// A closed axis-aligned float box; empty when min > max on some axis, as a default-made one
/// (+inf, -inf) is, so growing it by anything gives exactly that.
struct Box3f {
  Float3 min{std::numeric_limits<float>::infinity(), std::numeric_limits<float>::infinity(),
             std::numeric_limits<float>::infinity()};
  Float3 max{-std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
             -std::numeric_limits<float>::infinity()};

  constexpr void grow(const Float3& p) {
    min.x = std::min(min.x, p.x), max.x = std::max(max.x, p.x);
    min.y = std::min(min.y, p.y), max.y = std::max(max.y, p.y);
    min.z = std::min(min.z, p.z), max.z = std::max(max.z, p.z);
  }
  constexpr void grow(const Box3f& b) {
    min.x = std::min(min.x, b.min.x), max.x = std::max(max.x, b.max.x);
    min.y = std::min(min.y, b.min.y), max.y = std::max(max.y, b.max.y);
    min.z = std::min(min.z, b.min.z), max.z = std::max(max.z, b.max.z);
  }
  constexpr bool empty() const { return min.x > max.x || min.y > max.y || min.z > max.z; }
  /// Half the surface area (0 when empty): the SAH only ever uses ratios.
  constexpr float half_area() const {
    if (empty()) return 0.0f;
    const float dx = max.x - min.x, dy = max.y - min.y, dz = max.z - min.z;
    return dx * dy + dy * dz + dz * dx;
  }
  constexpr float centroid(int axis) const { return 0.5f * (at(min, axis) + at(max, axis)); }
  /// The common part of two boxes (empty when they do not overlap).
  static constexpr Box3f intersection(const Box3f& a, const Box3f& b) {
    Box3f r;
    r.min.x = std::max(a.min.x, b.min.x), r.max.x = std::min(a.max.x, b.max.x);
    r.min.y = std::max(a.min.y, b.min.y), r.max.y = std::min(a.max.y, b.max.y);
    r.min.z = std::max(a.min.z, b.min.z), r.max.z = std::min(a.max.z, b.max.z);
    return r;
  }
};
static_assert(sizeof(Box3f) == 24);

/// A closed axis-aligned double box.
struct Box3d {
  Double3 min, max;
};

/// A 2D point in double precision: longitude and latitude in degrees for a geographic layer
/// (x = lon, y = lat), else plain x and y. The 2D inputs (polygon layers, point tables) keep
/// their coordinates exactly as parsed.
struct Double2 {
  double x = 0, y = 0;
  friend constexpr bool operator==(const Double2&, const Double2&) = default;
};
static_assert(sizeof(Double2) == 16);

/// A closed axis-aligned 2D double box; empty when min > max on some axis, as a default-made
/// one (+inf, -inf) is.
struct Box2d {
  Double2 min{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()};
  Double2 max{-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};

  constexpr void grow(const Double2& p) {
    min.x = std::min(min.x, p.x), max.x = std::max(max.x, p.x);
    min.y = std::min(min.y, p.y), max.y = std::max(max.y, p.y);
  }
  constexpr void grow(const Box2d& b) {
    min.x = std::min(min.x, b.min.x), max.x = std::max(max.x, b.max.x);
    min.y = std::min(min.y, b.min.y), max.y = std::max(max.y, b.max.y);
  }
  constexpr bool empty() const { return min.x > max.x || min.y > max.y; }
  /// Whether `p` lies in the closed box.
  constexpr bool contains(const Double2& p) const {
    return p.x >= min.x && p.x <= max.x && p.y >= min.y && p.y <= max.y;
  }
  /// Whether the closed boxes share a point.
  constexpr bool overlaps(const Box2d& b) const {
    return b.min.x <= max.x && min.x <= b.max.x && b.min.y <= max.y && min.y <= b.max.y;
  }
};
static_assert(sizeof(Box2d) == 32);

}  // namespace kiln::format
