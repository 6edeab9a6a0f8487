// The ESVO ray cast of Laine & Karras 2010 (their Appendix's kernel, restated). The octree is
// the cube [1,2]^3 and the ray is mirrored per axis so its direction is negative everywhere:
// the child it enters next is then always found by stepping coordinates down, and the cube a
// voxel occupies is read off the float bits of its corner. At each level the stack keeps the
// parent and the ray's exit from it; on POP, the highest bit in which the old and new corner
// differ names the level to return to (read from a float's exponent). Before descending into a
// voxel, the ray's span is cut by the voxel's contour slab; a leaf whose cut span is not empty
// is the hit.
#include <bit>
#include <cmath>
#include <utility>

#include "kiln/runtime/esvo.hpp"

namespace kiln {

namespace {

constexpr int kMaxScale = 23;  // float mantissa bits: the deepest level the bit tricks reach
// A safety net for degenerate input only: a finite ray crosses far fewer cells.
constexpr std::uint32_t kMaxIterations = 1u << 24;

std::uint32_t bits_of(float f) {
  return std::bit_cast<std::uint32_t>(f);
}
float float_of(std::uint32_t u) {
  return std::bit_cast<float>(u);
}

// The kernel's variables: the ray in octree space and mirrored (t = x * coef - bias on each
// axis), the span [t_min, t_max] still to search in the parent, the current voxel (its octant
// idx in the mirrored parent, its corner pos, its size scale_exp2 = 2^(scale - kMaxScale)) and
// the stack of (parent, t_max) per scale.
struct CastState {
  struct Frame {
    std::uint64_t parent;
    float t_max;
  };
  float o[3], d[3];
  float coef[3], bias[3];
  std::uint32_t mirror = 0;
  float t_min = 0, t_max = 0;
  int entry_axis = 0;                  // surface entered: -1 none, 0..2 a cube face, 3 a contour
  float entry_contour[3] = {0, 0, 0};  // the contour's normal when entry_axis == 3
  std::uint64_t parent = 0;
  std::uint32_t idx = 0;
  float pos[3] = {1, 1, 1};
  int scale = kMaxScale - 1;
  float scale_exp2 = 0.5f;
  Frame stack[kMaxScale + 1];
};

// The ray in octree space ([1,2]^3, t kept the world-space parameter); false when it cannot
// hit (non-finite, or no direction). Tiny direction components would divide by zero; the paper
// clamps them to 2^-23 of the direction.
inline bool to_octree_ray(const Ray& ray, const VoxelGridFrame& frame, double to_octree,
                          CastState& s) {
  const float org[3] = {ray.org.x, ray.org.y, ray.org.z};
  const float dir[3] = {ray.dir.x, ray.dir.y, ray.dir.z};
  for (int a = 0; a < 3; ++a) {
    s.o[a] = float(1.0 + (double(org[a]) - frame.origin[a]) * to_octree);
    s.d[a] = float(double(dir[a]) * to_octree);  // so t stays the world-space parameter
    if (!std::isfinite(s.o[a]) || !std::isfinite(s.d[a])) return false;
  }
  if (std::isnan(ray.tmin) || std::isnan(ray.tmax)) return false;
  const float d_max = std::fmax(std::fabs(s.d[0]), std::fmax(std::fabs(s.d[1]), std::fabs(s.d[2])));
  // So tiny that 1 / eps (the slab coefficients) would overflow: such a ray needs t > 2^104 to
  // cross the octree (a direction tiny against the grid, or a grid huge against float range),
  // and infinite coefficients would make NaN distances. A miss.
  if (!(d_max >= 0x1p-104f)) return false;
  const float eps = d_max * 0x1p-23f;
  for (float& c : s.d)
    if (std::fabs(c) < eps) c = std::copysign(eps, c);
  return true;
}

// Mirrors the ray, clips it to the root cube and [ray.tmin, ray.tmax] (the entry axis gives the
// face normal) and picks the first child; false when it misses the root.
inline bool enter_root(const Ray& ray, CastState& s) {
  for (int a = 0; a < 3; ++a) {
    s.coef[a] = 1.0f / -std::fabs(s.d[a]);
    s.bias[a] = s.coef[a] * s.o[a];
    if (s.d[a] > 0) s.mirror |= 1u << a, s.bias[a] = 3.0f * s.coef[a] - s.bias[a];
  }
  s.entry_axis = 0;
  s.t_min = 2.0f * s.coef[0] - s.bias[0];
  for (int a = 1; a < 3; ++a)
    if (2.0f * s.coef[a] - s.bias[a] > s.t_min)
      s.t_min = 2.0f * s.coef[a] - s.bias[a], s.entry_axis = a;
  s.t_max =
      std::fmin(s.coef[0] - s.bias[0], std::fmin(s.coef[1] - s.bias[1], s.coef[2] - s.bias[2]));
  if (!(s.t_min > ray.tmin)) s.t_min = ray.tmin, s.entry_axis = -1;
  s.t_max = std::fmin(s.t_max, ray.tmax);
  if (!(s.t_min <= s.t_max)) return false;
  for (int a = 0; a < 3; ++a)
    if (1.5f * s.coef[a] - s.bias[a] > s.t_min) s.idx ^= 1u << a, s.pos[a] = 1.5f;
  return true;
}

// Cuts the current voxel's span [tv_min, tv_max] by its contour slab: n . (p(t) - centre)
// against the slab, all in octree units of the voxel's size. True when the slab's entry set
// tv_min.
inline bool cut_by_contour(const CastState& s, const format::Contour& contour, float& tv_min,
                           float& tv_max) {
  const float half = s.scale_exp2 * 0.5f;
  float no = 0, nd = 0;
  for (int a = 0; a < 3; ++a) {
    const float centre = (s.mirror >> a & 1) ? 3.0f - (s.pos[a] + half) : s.pos[a] + half;
    no += float(contour.normal[a]) * (s.o[a] - centre);
    nd += float(contour.normal[a]) * s.d[a];
  }
  const float unit = float(format::contour_extent(contour)) * (1.0f / 128.0f) * s.scale_exp2;
  const float lo = float(contour.position) * unit;
  const float hi = float(contour.position + contour.thickness) * unit;
  if (nd == 0.0f) {
    if (no < lo || no > hi) tv_max = -INFINITY;
    return false;
  }
  float t0 = (lo - no) / nd, t1 = (hi - no) / nd;
  if (t0 > t1) std::swap(t0, t1);
  bool entered = false;
  if (t0 > tv_min) tv_min = t0, entered = true;
  tv_max = std::fmin(tv_max, t1);
  return entered;
}

// The outward normal of the surface the ray entered last: a cube face or a contour's plane;
// stays 0 when the ray starts inside.
inline void entered_normal(const CastState& s, float normal[3]) {
  if (s.entry_axis >= 0 && s.entry_axis < 3) {
    normal[s.entry_axis] = s.d[s.entry_axis] > 0 ? -1.0f : 1.0f;
  } else if (s.entry_axis == 3) {
    const float* n = s.entry_contour;
    const float dn = n[0] * s.d[0] + n[1] * s.d[1] + n[2] * s.d[2];
    const float length = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    const float sign = (dn > 0 ? -1.0f : 1.0f) / length;
    for (int a = 0; a < 3; ++a) normal[a] = n[a] * sign;
  }
}

// The hit on the current voxel (a leaf, or a voxel coarse enough for the LOD) at tv_min: its
// level, the finest-grid voxel holding the hit point (clamped into the voxel's cube) and the
// entered surface's normal.
inline void leaf_hit(const CastState& s, float tv_min, std::uint32_t resolution, VoxelHit& hit) {
  hit.level = std::uint32_t(kMaxScale - s.scale);
  hit.t = tv_min;
  hit.prim = 0;
  const float n = float(resolution);
  const auto cells = std::uint32_t(resolution >> hit.level);
  std::uint32_t cell[3];
  for (int a = 0; a < 3; ++a) {
    const float corner = (s.mirror >> a & 1) ? 3.0f - s.pos[a] - s.scale_exp2 : s.pos[a];
    const auto first = std::uint32_t((corner - 1.0f) * n);
    const float at = ((s.o[a] + tv_min * s.d[a]) - 1.0f) * n;
    const float rel = std::floor(at) - float(first);
    cell[a] = first + (!(rel >= 0) ? 0 : rel >= float(cells) ? cells - 1 : std::uint32_t(rel));
  }
  hit.x = cell[0], hit.y = cell[1], hit.z = cell[2];
  entered_normal(s, hit.face_normal);
}

// PUSH: descend into the current voxel, the descriptor at word `child`, whose subtree is
// searched within [tv_min, tv_max]; tc are the current voxel's exits per axis.
inline void push(CastState& s, std::uint64_t child, const float tc[3], float tv_min, float tv_max) {
  const float half = s.scale_exp2 * 0.5f;
  s.stack[s.scale] = {s.parent, s.t_max};
  s.parent = child;
  s.idx = 0;
  --s.scale;
  s.scale_exp2 = half;
  for (int a = 0; a < 3; ++a)
    if (half * s.coef[a] + tc[a] > tv_min) s.idx ^= 1u << a, s.pos[a] += half;
  s.t_min = tv_min;
  s.t_max = tv_max;
}

// ADVANCE to the next sibling along the ray, leaving the current voxel at tc_max; when that
// leaves the parent, POP to the level left behind (the highest differing bit of the stepped
// coordinates) and set `popped`. False when the ray leaves the octree.
inline bool advance(CastState& s, const float tc[3], float tc_max, bool& popped) {
  std::uint32_t step = 0;
  for (int a = 0; a < 3; ++a)
    if (tc[a] <= tc_max) step |= 1u << a, s.pos[a] -= s.scale_exp2;
  s.t_min = tc_max;
  s.entry_axis = std::countr_zero(step | 8u);
  s.idx ^= step;
  if ((s.idx & step) == 0) return true;
  std::uint32_t differing = 0;
  for (int a = 0; a < 3; ++a)
    if (step >> a & 1) differing |= bits_of(s.pos[a]) ^ bits_of(s.pos[a] + s.scale_exp2);
  s.scale = int(bits_of(float(differing)) >> 23) - 127;
  if (s.scale >= kMaxScale) return false;
  s.scale_exp2 = float_of(std::uint32_t(s.scale - kMaxScale + 127) << 23);
  s.parent = s.stack[s.scale].parent;
  s.t_max = s.stack[s.scale].t_max;
  s.idx = 0;
  for (int a = 0; a < 3; ++a) {
    const std::uint32_t shifted = bits_of(s.pos[a]) >> s.scale;
    s.pos[a] = float_of(shifted << s.scale);
    s.idx |= (shifted & 1) << a;
  }
  popped = true;
  return true;
}

}  // namespace

template <bool kAnyHit, bool kCount>
VoxelHit EsvoView::cast(const Ray& ray, const EsvoLod& lod, Cost* cost) const {
  VoxelHit hit;
  const double to_octree = 1.0 / (double(frame_.resolution) * frame_.voxel_size);
  CastState s;
  if (!to_octree_ray(ray, frame_, to_octree, s) || !enter_root(ray, s)) return hit;
  const float lod_coef = float(lod.coef * to_octree), lod_bias = float(lod.bias * to_octree);
  const bool use_lod = lod.coef > 0 || lod.bias > 0;
  std::uint32_t w0 = 0, w1 = 0;
  bool popped = true;  // the parent's descriptor is still to load
  for (std::uint32_t iteration = 0; s.scale < kMaxScale && iteration < kMaxIterations;
       ++iteration) {
    if (popped) {
      w0 = words_[s.parent], w1 = words_[s.parent + 1], popped = false;
      if constexpr (kCount) cost->nodes += 1;
    }
    if constexpr (kCount) cost->tests += 1;
    float tc[3];
    for (int a = 0; a < 3; ++a) tc[a] = s.pos[a] * s.coef[a] - s.bias[a];
    const float tc_max = std::fmin(tc[0], std::fmin(tc[1], tc[2]));
    const std::uint32_t octant = s.idx ^ s.mirror;
    if ((w0 >> 8 >> octant & 1) != 0 && s.t_min <= s.t_max) {
      float tv_min = s.t_min, tv_max = std::fmin(s.t_max, tc_max);
      bool contour_entry = false;
      format::Contour contour{};
      if ((w1 >> octant & 1) != 0) {
        contour = format::decode_contour(
            words_[s.parent + (w1 >> 8) + 1 + format::rank_below(w1 & 0xFF, octant)]);
        contour_entry = cut_by_contour(s, contour, tv_min, tv_max);
      }
      if (tv_min <= tv_max) {
        // The slab's plane is the surface entered, at a leaf hit or for the subtree below.
        if (contour_entry) {
          s.entry_axis = 3;
          for (int a = 0; a < 3; ++a) s.entry_contour[a] = float(contour.normal[a]);
        }
        const bool leaf = (w0 >> octant & 1) == 0;
        if (leaf || (use_lod && tc_max * lod_coef + lod_bias >= s.scale_exp2)) {
          leaf_hit(s, tv_min, frame_.resolution, hit);
          if constexpr (!kAnyHit) {
            const std::uint64_t attachment = attachment_index(s.parent, w0, w1, octant);
            format::decode_octahedral(normals_[attachment], hit.normal);
            if (!colors_.empty()) hit.color = colors_[attachment];
          }
          return hit;
        }
        push(s,
             format::first_child_word(words_.data(), s.parent, w0) +
                 2 * format::rank_below(w0 & 0xFF, octant),
             tc, tv_min, tv_max);
        popped = true;
        continue;
      }
    }
    if (!advance(s, tc, tc_max, popped)) break;
  }
  return hit;
}

VoxelHit EsvoView::intersect(const Ray& ray) const {
  return cast<false, false>(ray, {}, nullptr);
}
VoxelHit EsvoView::intersect(const Ray& ray, const EsvoLod& lod) const {
  return cast<false, false>(ray, lod, nullptr);
}

VoxelHit EsvoView::intersect_counting(const Ray& ray, Cost& cost) const {
  return cast<false, true>(ray, {}, &cost);
}
VoxelHit EsvoView::intersect_counting(const Ray& ray, Cost& cost, const EsvoLod& lod) const {
  return cast<false, true>(ray, lod, &cost);
}

VoxelHit EsvoView::intersect_any(const Ray& ray) const {
  return cast<true, false>(ray, {}, nullptr);
}
VoxelHit EsvoView::intersect_any(const Ray& ray, const EsvoLod& lod) const {
  return cast<true, false>(ray, lod, nullptr);
}

bool EsvoView::occluded(const Ray& ray) const {
  return cast<true, false>(ray, {}, nullptr).hit();
}
bool EsvoView::occluded(const Ray& ray, const EsvoLod& lod) const {
  return cast<true, false>(ray, lod, nullptr).hit();
}

}  // namespace kiln
