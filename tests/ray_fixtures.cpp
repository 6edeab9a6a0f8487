// Generated scenes and rays shared by the traversal tests, and the brute-force reference.
#include "ray_fixtures.hpp"

#include <cmath>
#include <map>
#include <random>

#include "kiln/runtime/watertight.hpp"

namespace kiln::test {

using format::Float3;

float tri_t(const Scene& scene, std::uint32_t prim, const Ray& ray, float tmax) {
  const auto& t = scene.triangles[prim];
  float h, u, v;
  if (!intersect_watertight(prepare_watertight(ray), scene.positions[t.v[0]],
                            scene.positions[t.v[1]], scene.positions[t.v[2]], ray.tmin, tmax, h, u,
                            v))
    return INFINITY;
  return h;
}

Hit brute_force(const Scene& scene, const Ray& ray) {
  Hit best;
  float tmax = ray.tmax;
  const WatertightRay w = prepare_watertight(ray);
  for (std::uint32_t i = 0; i < scene.triangles.size(); ++i) {
    const auto& t = scene.triangles[i];
    float h, u, v;
    if (intersect_watertight(w, scene.positions[t.v[0]], scene.positions[t.v[1]],
                             scene.positions[t.v[2]], ray.tmin, tmax, h, u, v)) {
      tmax = h;
      best = {h, i, u, v};
    }
  }
  return best;
}

Scene make_scene(std::vector<Float3> positions, std::vector<format::Triangle> triangles) {
  Scene s;
  s.positions = std::move(positions);
  s.triangles = std::move(triangles);
  s.triangle_mesh.assign(s.triangles.size(), 0);
  s.meshes.push_back({"generated", 0, 0, s.triangles.size(), 0, s.positions.size()});
  s.sources.push_back({"generated", 0, 0});
  s.bounds = bounds_of(s.positions);
  s.input_triangle_count = s.triangles.size();
  return s;
}

void add_triangle(std::vector<Float3>& p, std::vector<format::Triangle>& t, Float3 a, Float3 b,
                  Float3 c) {
  const auto base = std::uint32_t(p.size());
  p.push_back(a), p.push_back(b), p.push_back(c);
  t.push_back({base, base + 1, base + 2});
}

// Worst cases named in the issue, generated from a fixed seed.
std::map<std::string, Scene> worst_cases() {
  std::map<std::string, Scene> cases;
  std::mt19937 rng(1234);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  auto point = [&](float scale, float offset = 0) {
    return Float3{offset + scale * unit(rng), offset + scale * unit(rng),
                  offset + scale * unit(rng)};
  };
  {  // many large, mutually overlapping triangles
    std::vector<Float3> p;
    std::vector<format::Triangle> t;
    for (int i = 0; i < 1500; ++i) add_triangle(p, t, point(1), point(1), point(1));
    cases["overlapping"] = make_scene(p, t);
  }
  {  // needle-thin slivers
    std::vector<Float3> p;
    std::vector<format::Triangle> t;
    for (int i = 0; i < 1500; ++i) {
      const Float3 a = point(1), b = point(1);
      const Float3 c{0.5f * (a.x + b.x) + 1e-6f, 0.5f * (a.y + b.y), 0.5f * (a.z + b.z) + 1e-6f};
      add_triangle(p, t, a, b, c);
    }
    cases["slivers"] = make_scene(p, t);
  }
  {  // stacks of axis-parallel planes, each a grid of triangles
    std::vector<Float3> p;
    std::vector<format::Triangle> t;
    for (int axis = 0; axis < 3; ++axis)
      for (int layer = 0; layer < 4; ++layer)
        for (int i = 0; i < 8; ++i)
          for (int j = 0; j < 8; ++j) {
            auto at = [&](float u, float v) {
              const float w = 0.2f * float(layer) + 0.1f;
              return axis == 0 ? Float3{w, u, v} : axis == 1 ? Float3{u, w, v} : Float3{u, v, w};
            };
            const float u0 = i / 8.0f, u1 = (i + 1) / 8.0f, v0 = j / 8.0f, v1 = (j + 1) / 8.0f;
            add_triangle(p, t, at(u0, v0), at(u1, v0), at(u1, v1));
            add_triangle(p, t, at(u0, v0), at(u1, v1), at(u0, v1));
          }
    cases["axis_planes"] = make_scene(p, t);
  }
  {  // a huge triangle with a cluster of tiny ones: the teapot in a stadium
    std::vector<Float3> p;
    std::vector<format::Triangle> t;
    add_triangle(p, t, {-1e4f, -1e4f, -0.5f}, {1e4f, -1e4f, 0.5f}, {0, 1e4f, 0});
    for (int i = 0; i < 1500; ++i) {
      const Float3 c = point(0.01f);
      add_triangle(p, t, c, {c.x + 1e-3f, c.y, c.z}, {c.x, c.y + 1e-3f, c.z + 5e-4f});
    }
    cases["teapot_in_stadium"] = make_scene(p, t);
  }
  return cases;
}

// Rays from random points toward random points in the scene's box (plus axis-aligned ones,
// which exercise the slab test's infinities).
std::vector<Ray> box_rays(const Scene& s, std::size_t count) {
  std::mt19937 rng(99);
  std::uniform_real_distribution<float> unit(-0.2f, 1.2f);
  auto in_box = [&] {
    return Float3{s.bounds.min.x + (s.bounds.max.x - s.bounds.min.x) * unit(rng),
                  s.bounds.min.y + (s.bounds.max.y - s.bounds.min.y) * unit(rng),
                  s.bounds.min.z + (s.bounds.max.z - s.bounds.min.z) * unit(rng)};
  };
  std::vector<Ray> rays;
  for (std::size_t i = 0; i < count; ++i) {
    const Float3 o = in_box(), target = in_box();
    Float3 d{target.x - o.x, target.y - o.y, target.z - o.z};
    if (i % 4 == 0)
      d = i % 12 == 0 ? Float3{1, 0, 0} : i % 12 == 4 ? Float3{0, -1, 0} : Float3{0, 0, 1};
    rays.push_back({o, 0.0f, d, INFINITY});
  }
  return rays;
}

// An icosphere subdivided four times (5120 triangles, closed): rays from inside aimed exactly at
// every vertex and every edge midpoint must all hit.
Scene icosphere(int subdivisions) {
  const float g = (1.0f + std::sqrt(5.0f)) / 2.0f;
  std::vector<Float3> p = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0},
                           {0, -1, g}, {0, 1, g}, {0, -1, -g}, {0, 1, -g},
                           {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
  std::vector<format::Triangle> t = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                     {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                     {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                     {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  auto normalize = [](Float3 v) {
    const float l = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
    return Float3{v.x / l, v.y / l, v.z / l};
  };
  for (auto& v : p) v = normalize(v);
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> midpoint;
    auto mid = [&](std::uint32_t a, std::uint32_t b) {
      const auto key = std::minmax(a, b);
      if (const auto it = midpoint.find(key); it != midpoint.end()) return it->second;
      p.push_back(normalize({(p[a].x + p[b].x) / 2, (p[a].y + p[b].y) / 2, (p[a].z + p[b].z) / 2}));
      return midpoint[key] = std::uint32_t(p.size() - 1);
    };
    std::vector<format::Triangle> next;
    for (const auto& tri : t) {
      const auto a = mid(tri.v[0], tri.v[1]), b = mid(tri.v[1], tri.v[2]),
                 c = mid(tri.v[2], tri.v[0]);
      next.push_back({tri.v[0], a, c});
      next.push_back({tri.v[1], b, a});
      next.push_back({tri.v[2], c, b});
      next.push_back({a, b, c});
    }
    t = std::move(next);
  }
  return make_scene(p, t);
}

}  // namespace kiln::test
