#include "kiln/tools/ray_generator.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

#include "kiln/runtime/parallel.hpp"
#include "kiln/runtime/triangle_geometry.hpp"
#include "kiln/tools/split_mix64.hpp"

namespace kiln {

namespace {

struct Camera {
  format::Double3 eye, forward, right, up;
  double tan_half_fov;
};

Camera frame_bounds(const RayScene& s) {
  const format::Double3 lo = to_d(s.bounds_min), hi = to_d(s.bounds_max);
  const format::Double3 center = (lo + hi) * 0.5;
  const double radius = std::max(1e-6, std::sqrt(dot(hi - lo, hi - lo)) * 0.5);
  Camera c;
  c.tan_half_fov = std::tan(0.5 * 50.0 * 3.14159265358979323846 / 180.0);
  const format::Double3 view = normalize(format::Double3{0.45, 0.35, 1.0});
  c.eye = center + view * (radius / std::sin(0.5 * 50.0 * 3.14159265358979323846 / 180.0));
  c.forward = normalize(center - c.eye);
  c.right = normalize(cross(c.forward, format::Double3{0, 1, 0}));
  c.up = cross(c.right, c.forward);
  return c;
}

Camera from_eye(const RayCamera& rc) {
  Camera c;
  c.eye = to_d(rc.eye);
  c.forward = normalize(to_d(rc.target) - c.eye);
  // Looking straight up or down: any right vector will do.
  const format::Double3 up_hint =
      std::fabs(c.forward.y) > 0.999 ? format::Double3{0, 0, 1} : format::Double3{0, 1, 0};
  c.right = normalize(cross(c.forward, up_hint));
  c.up = cross(c.right, c.forward);
  c.tan_half_fov = std::tan(0.5 * double(rc.fov_degrees) * 3.14159265358979323846 / 180.0);
  return c;
}

Ray primary_ray(const Camera& c, SplitMix64& rng) {
  const double sx = (2 * rng.uniform() - 1) * c.tan_half_fov;
  const double sy = (2 * rng.uniform() - 1) * c.tan_half_fov;
  const format::Double3 dir = normalize(c.forward + c.right * sx + c.up * sy);
  return {to_f(c.eye), 0.0f, to_f(dir), std::numeric_limits<float>::infinity()};
}

std::vector<Ray> generate_from(const RayScene& s, const Camera& camera, RayKind kind,
                               std::size_t count, std::uint64_t seed, unsigned threads) {
  SplitMix64 rng(seed);
  std::vector<Ray> rays;
  rays.reserve(count);
  if (kind == RayKind::kPrimary) {
    for (std::size_t i = 0; i < count; ++i) rays.push_back(primary_ray(camera, rng));
    return rays;
  }
  const format::Double3 lo = to_d(s.bounds_min), hi = to_d(s.bounds_max);
  const double radius = std::max(1e-6, std::sqrt(dot(hi - lo, hi - lo)) * 0.5);
  const format::Double3 light = (lo + hi) * 0.5 + format::Double3{0.3, 1.6, 0.2} * radius;
  const double offset = 1e-4 * radius;
  std::size_t attempts = 0;
  while (rays.size() < count) {
    // Candidates in order from one stream, traced as a batch, consumed in order: the result
    // does not depend on the thread count.
    const std::size_t batch = std::max<std::size_t>(1024, count - rays.size());
    attempts += batch;
    if (attempts > 64 * count + 65536)
      throw std::runtime_error("too few primary rays hit the scene to generate secondary rays");
    std::vector<Ray> primaries(batch);
    for (auto& r : primaries) r = primary_ray(camera, rng);
    std::vector<Hit> hits(batch);
    parallel_for_batched(batch, kRaysPerTask, threads,
                         [&](std::size_t i) { hits[i] = s.closest(primaries[i]); });
    for (std::size_t i = 0; i < batch && rays.size() < count; ++i) {
      if (hits[i].prim == kNoHit) continue;
      const auto& t = s.triangles[hits[i].prim];
      const format::Double3 a = to_d(s.positions[t.v[0]]), b = to_d(s.positions[t.v[1]]),
                            c = to_d(s.positions[t.v[2]]);
      format::Double3 n = cross(b - a, c - a);
      if (dot(n, n) == 0) continue;
      n = normalize(n);
      const format::Double3 dir = to_d(primaries[i].dir);
      if (dot(n, dir) > 0) n = n * -1.0;
      const format::Double3 p = to_d(primaries[i].org) + dir * double(hits[i].t) + n * offset;
      if (kind == RayKind::kDiffuse) {
        // Cosine-weighted hemisphere around n (Malley's method).
        const double u1 = rng.uniform(), u2 = rng.uniform();
        const double r = std::sqrt(u1), phi = 2 * 3.14159265358979323846 * u2;
        const format::Double3 tangent =
            normalize(std::fabs(n.x) > 0.9 ? cross(n, format::Double3{0, 1, 0})
                                           : cross(n, format::Double3{1, 0, 0}));
        const format::Double3 bitangent = cross(n, tangent);
        const format::Double3 d =
            normalize(tangent * (r * std::cos(phi)) + bitangent * (r * std::sin(phi)) +
                      n * std::sqrt(std::max(0.0, 1 - u1)));
        rays.push_back({to_f(p), 0.0f, to_f(d), std::numeric_limits<float>::infinity()});
      } else {
        const format::Double3 to_light = light - p;
        const double distance = std::sqrt(dot(to_light, to_light));
        rays.push_back(
            {to_f(p), 0.0f, to_f(to_light * (1.0 / distance)), float(distance * (1 - 1e-4))});
      }
    }
  }
  return rays;
}

}  // namespace

std::vector<Ray> generate_rays(const RayScene& s, RayKind kind, std::size_t count,
                               std::uint64_t seed, unsigned threads) {
  return generate_from(s, frame_bounds(s), kind, count, seed, threads);
}

std::vector<Ray> generate_rays(const RayScene& s, const RayCamera& camera, RayKind kind,
                               std::size_t count, std::uint64_t seed, unsigned threads) {
  return generate_from(s, from_eye(camera), kind, count, seed, threads);
}

}  // namespace kiln
