// Generated scenes and rays shared by the traversal tests, and the brute-force reference.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "kiln/compiler/scene.hpp"
#include "kiln/runtime/ray.hpp"

namespace kiln::test {

// t of the ray's hit on one triangle (watertight test), or +inf.
float tri_t(const Scene& scene, std::uint32_t prim, const Ray& ray, float tmax);
// Every triangle against the ray with the same watertight test: the reference.
Hit brute_force(const Scene& scene, const Ray& ray);

Scene make_scene(std::vector<format::Float3> positions, std::vector<format::Triangle> triangles);
void add_triangle(std::vector<format::Float3>& p, std::vector<format::Triangle>& t,
                  format::Float3 a, format::Float3 b, format::Float3 c);
// Overlapping, sliver, axis-plane and teapot-in-a-stadium scenes from a fixed seed.
std::map<std::string, Scene> worst_cases();
// Rays between random points around the scene's box, a quarter of them axis-aligned.
std::vector<Ray> box_rays(const Scene& s, std::size_t count);
// A closed icosphere: 20 x 4^subdivisions triangles.
Scene icosphere(int subdivisions);

// Closest and any hit of a structure against brute force: hit/miss equal, t within 1e-5
// relative, primitive equal unless both are at exactly the same t. Stops after five failures.
template <class View>
void expect_agrees_with_brute_force(const Scene& scene, const View& bvh,
                                    std::span<const Ray> rays) {
  std::size_t mismatches = 0;
  for (std::size_t i = 0; i < rays.size() && mismatches < 5; ++i) {
    const Hit expected = brute_force(scene, rays[i]);
    const Hit got = bvh.intersect(rays[i]);
    const bool ok_hit = (expected.prim == kNoHit) == (got.prim == kNoHit);
    bool ok = ok_hit;
    if (ok && got.prim != kNoHit) {
      ok = std::fabs(got.t - expected.t) <= 1e-5f * std::fabs(expected.t);
      if (got.prim != expected.prim)
        ok = ok && tri_t(scene, got.prim, rays[i], INFINITY) == expected.t;
    }
    const bool occluded = bvh.occluded(rays[i]);
    if (occluded != (expected.prim != kNoHit)) ok = false;
    if (!ok) {
      ++mismatches;
      ADD_FAILURE() << "ray " << i << ": brute force prim " << expected.prim << " t " << expected.t
                    << ", bvh prim " << got.prim << " t " << got.t << ", occluded " << occluded;
    }
  }
}

}  // namespace kiln::test
