#include "kiln/bench/generated_scenes.hpp"

#include <algorithm>
#include <cmath>

#include "kiln/tools/split_mix64.hpp"

namespace kiln::bench {

namespace {

constexpr double kPi = 3.14159265358979323846;

format::Float3 f3(double x, double y, double z) {
  return {float(x), float(y), float(z)};
}

// A uniformly distributed unit vector (Archimedes: z uniform, angle uniform).
void unit_vector(SplitMix64& rng, double out[3]) {
  const double z = 2 * rng.uniform() - 1, phi = 2 * kPi * rng.uniform();
  const double r = std::sqrt(std::max(0.0, 1 - z * z));
  out[0] = r * std::cos(phi), out[1] = r * std::sin(phi), out[2] = z;
}

std::uint32_t add_vertex(GeneratedMesh& mesh, format::Float3 p) {
  mesh.positions.push_back(p);
  return std::uint32_t(mesh.positions.size() - 1);
}

// A UV sphere of radius `radius` with about `count` triangles (rings x segments quads).
void add_sphere(GeneratedMesh& mesh, std::uint64_t count, double radius) {
  const auto segments = std::uint32_t(std::max(8.0, std::sqrt(double(count))));
  const auto rings = std::uint32_t(std::max<std::uint64_t>(4, count / (2 * segments)));
  const auto first = std::uint32_t(mesh.positions.size());
  for (std::uint32_t r = 0; r <= rings; ++r)
    for (std::uint32_t s = 0; s <= segments; ++s) {
      const double theta = kPi * r / rings, phi = 2 * kPi * s / segments;
      add_vertex(mesh, f3(radius * std::sin(theta) * std::cos(phi), radius * std::cos(theta),
                          radius * std::sin(theta) * std::sin(phi)));
    }
  const std::uint32_t row = segments + 1;
  for (std::uint32_t r = 0; r < rings; ++r)
    for (std::uint32_t s = 0; s < segments; ++s) {
      const std::uint32_t a = first + r * row + s, b = a + 1, c = a + row, d = c + 1;
      if (r > 0) mesh.triangles.push_back({{a, b, d}});  // the poles' quads are triangles
      if (r + 1 < rings) mesh.triangles.push_back({{a, d, c}});
    }
}

// A surface of revolution about y through the profile points (radius, height), `segments`
// around, its vertices jittered by up to `jitter` (seeded).
void add_revolution(GeneratedMesh& mesh, const std::vector<std::pair<double, double>>& profile,
                    std::uint32_t segments, double jitter, SplitMix64& rng) {
  const auto first = std::uint32_t(mesh.positions.size());
  for (const auto& [radius, height] : profile)
    for (std::uint32_t s = 0; s < segments; ++s) {
      const double phi = 2 * kPi * s / segments;
      add_vertex(mesh, f3(radius * std::cos(phi) + jitter * (rng.uniform() - 0.5),
                          height + jitter * (rng.uniform() - 0.5),
                          radius * std::sin(phi) + jitter * (rng.uniform() - 0.5)));
    }
  for (std::uint32_t p = 0; p + 1 < profile.size(); ++p)
    for (std::uint32_t s = 0; s < segments; ++s) {
      const std::uint32_t a = first + p * segments + s,
                          b = first + p * segments + (s + 1) % segments, c = a + segments,
                          d = b + segments;
      mesh.triangles.push_back({{a, b, d}});
      mesh.triangles.push_back({{a, d, c}});
    }
}

}  // namespace

GeneratedMesh uniform_triangles(std::uint64_t count, std::uint64_t seed) {
  GeneratedMesh mesh;
  SplitMix64 rng(seed);
  const double size = 0.5 / std::cbrt(double(std::max<std::uint64_t>(count, 1)));
  for (std::uint64_t t = 0; t < count; ++t) {
    const double c[3] = {rng.uniform(), rng.uniform(), rng.uniform()};
    format::Triangle tri{};
    for (std::uint32_t& v : tri.v) {
      double d[3];
      unit_vector(rng, d);
      v = add_vertex(mesh, f3(c[0] + size * d[0], c[1] + size * d[1], c[2] + size * d[2]));
    }
    mesh.triangles.push_back(tri);
  }
  return mesh;
}

GeneratedMesh teapot_in_stadium(std::uint64_t count, std::uint64_t seed) {
  GeneratedMesh mesh;
  SplitMix64 rng(seed);
  const std::uint64_t stadium = std::max<std::uint64_t>(256, count / 50);
  add_sphere(mesh, count > stadium ? count - stadium : 64, 1.0);
  // Ground, terraced bowl and wall: each band of the profile is 2 x segments triangles.
  const std::vector<std::pair<double, double>> profile = {
      {1.5, -2}, {120, -2}, {200, 10}, {260, 30}, {330, 60}, {400, 100}, {400, 160}};
  const auto segments = std::uint32_t(std::max<std::uint64_t>(8, stadium / (2 * 6)));
  add_revolution(mesh, profile, segments, 2.0, rng);
  return mesh;
}

}  // namespace kiln::bench
