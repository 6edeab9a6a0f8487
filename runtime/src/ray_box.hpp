// The conservative ray-box slab test shared by every ray walk over a tree of boxes or a tree's
// root cell.
#pragma once

#include <limits>

#include "kiln/runtime/ray.hpp"

namespace kiln {

// Slab test made conservative (pbrt-v4's 1 + 2 gamma(3) on the far distance) so rounding never
// culls a box the ray actually touches: watertightness needs the boxes to be watertight too.
constexpr float kFarScale = 1.0f + 2.0f * (3.0f * 0x1p-24f) / (1.0f - 3.0f * 0x1p-24f);

struct BoxRay {
  float org[3];
  float inv_dir[3];
  int negative[3];
};

inline BoxRay prepare_box_ray(const Ray& ray) {
  BoxRay b{};
  const float dir[3] = {ray.dir.x, ray.dir.y, ray.dir.z};
  const float org[3] = {ray.org.x, ray.org.y, ray.org.z};
  for (int a = 0; a < 3; ++a) {
    b.org[a] = org[a];
    b.inv_dir[a] = 1.0f / dir[a];  // +-inf for zero components: the slab test handles it
    b.negative[a] = b.inv_dir[a] < 0.0f;
  }
  return b;
}

// Narrows [tmin, tmax] to the part inside the box; false when nothing is left.
// A NaN slab distance (origin on a slab plane of an axis the ray runs parallel to) loses every
// comparison below, which leaves that axis unconstrained, as it should be.
inline bool clip_to_box(const float box_min[3], const float box_max[3], const BoxRay& r,
                        float& tmin, float& tmax) {
  for (int a = 0; a < 3; ++a) {
    const float lo = r.negative[a] ? box_max[a] : box_min[a];
    const float hi = r.negative[a] ? box_min[a] : box_max[a];
    const float t0 = (lo - r.org[a]) * r.inv_dir[a];
    const float t1 = (hi - r.org[a]) * r.inv_dir[a] * kFarScale;
    tmin = t0 > tmin ? t0 : tmin;
    tmax = t1 < tmax ? t1 : tmax;
  }
  return tmin <= tmax;
}

// Entry distance of the ray into a node's box (its `min` and `max` corners), or +inf when it
// misses within [tmin, tmax].
template <class BoxNode>
inline float enter_box(const BoxNode& n, const BoxRay& r, float tmin, float tmax) {
  return clip_to_box(n.min, n.max, r, tmin, tmax) ? tmin : std::numeric_limits<float>::infinity();
}

}  // namespace kiln
