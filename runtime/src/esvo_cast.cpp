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

#include "kiln/runtime/esvo.hpp"
#include "kiln/runtime/parallel.hpp"

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

}  // namespace

template <bool kAnyHit, bool kCount>
EsvoHit EsvoView::cast(const Ray& ray, const EsvoLod& lod, Cost* cost) const {
  EsvoHit out;
  const double to_octree = 1.0 / (double(frame_.resolution) * frame_.voxel_size);
  const float org[3] = {ray.org.x, ray.org.y, ray.org.z};
  const float dir[3] = {ray.dir.x, ray.dir.y, ray.dir.z};
  float o[3], d[3];
  for (int a = 0; a < 3; ++a) {
    o[a] = float(1.0 + (double(org[a]) - frame_.origin[a]) * to_octree);
    d[a] = float(double(dir[a]) * to_octree);  // so t stays the world-space parameter
    if (!std::isfinite(o[a]) || !std::isfinite(d[a])) return out;
  }
  if (std::isnan(ray.tmin) || std::isnan(ray.tmax)) return out;
  const float d_max = std::fmax(std::fabs(d[0]), std::fmax(std::fabs(d[1]), std::fabs(d[2])));
  if (!(d_max > 0)) return out;
  // Tiny components would divide by zero; the paper clamps them to 2^-23 of the direction.
  const float eps = d_max * 0x1p-23f;
  for (float& c : d)
    if (std::fabs(c) < eps) c = std::copysign(eps, c);

  float coef[3], bias[3];
  std::uint32_t mirror = 0;
  for (int a = 0; a < 3; ++a) {
    coef[a] = 1.0f / -std::fabs(d[a]);
    bias[a] = coef[a] * o[a];
    if (d[a] > 0) mirror |= 1u << a, bias[a] = 3.0f * coef[a] - bias[a];
  }
  // Entry and exit of the root cube; the entry axis gives the face normal.
  int entry_axis = 0;
  float t_min = 2.0f * coef[0] - bias[0];
  for (int a = 1; a < 3; ++a)
    if (2.0f * coef[a] - bias[a] > t_min) t_min = 2.0f * coef[a] - bias[a], entry_axis = a;
  float t_max = std::fmin(coef[0] - bias[0], std::fmin(coef[1] - bias[1], coef[2] - bias[2]));
  if (!(t_min > ray.tmin)) t_min = ray.tmin, entry_axis = -1;
  t_max = std::fmin(t_max, ray.tmax);
  if (!(t_min <= t_max)) return out;
  float entry_contour[3] = {0, 0, 0};  // valid when entry_axis == 3

  struct Frame {
    std::uint64_t parent;
    float t_max;
  };
  Frame stack[kMaxScale + 1];
  std::uint64_t parent = 0;
  std::uint32_t w0 = 0, w1 = 0;
  bool loaded = false;
  std::uint32_t idx = 0;
  float pos[3] = {1, 1, 1};
  int scale = kMaxScale - 1;
  float scale_exp2 = 0.5f;
  for (int a = 0; a < 3; ++a)
    if (1.5f * coef[a] - bias[a] > t_min) idx ^= 1u << a, pos[a] = 1.5f;
  const float lod_coef = float(lod.coef * to_octree), lod_bias = float(lod.bias * to_octree);
  const bool use_lod = lod.coef > 0 || lod.bias > 0;

  for (std::uint32_t iteration = 0; scale < kMaxScale && iteration < kMaxIterations; ++iteration) {
    if (!loaded) {
      w0 = words_[parent], w1 = words_[parent + 1], loaded = true;
      if constexpr (kCount) cost->nodes += 1;
    }
    if constexpr (kCount) cost->voxels += 1;
    float tc[3];
    for (int a = 0; a < 3; ++a) tc[a] = pos[a] * coef[a] - bias[a];
    const float tc_max = std::fmin(tc[0], std::fmin(tc[1], tc[2]));
    const std::uint32_t octant = idx ^ mirror;

    if ((w0 >> 8 >> octant & 1) != 0 && t_min <= t_max) {
      float tv_min = t_min, tv_max = std::fmin(t_max, tc_max);
      const float half = scale_exp2 * 0.5f;
      bool contour_entry = false;
      format::Contour contour{};
      if ((w1 >> octant & 1) != 0) {
        contour = format::decode_contour(
            words_[parent + (w1 >> 8) + 1 + format::rank_below(w1 & 0xFF, octant)]);
        // n . (p(t) - centre) against the slab, all in octree units of this voxel's size.
        float no = 0, nd = 0;
        for (int a = 0; a < 3; ++a) {
          const float centre = (mirror >> a & 1) ? 3.0f - (pos[a] + half) : pos[a] + half;
          no += float(contour.normal[a]) * (o[a] - centre);
          nd += float(contour.normal[a]) * d[a];
        }
        const float unit = float(format::contour_extent(contour)) * (1.0f / 128.0f) * scale_exp2;
        const float lo = float(contour.position) * unit;
        const float hi = float(contour.position + contour.thickness) * unit;
        if (nd == 0.0f) {
          if (no < lo || no > hi) tv_max = -INFINITY;
        } else {
          float t0 = (lo - no) / nd, t1 = (hi - no) / nd;
          if (t0 > t1) std::swap(t0, t1);
          if (t0 > tv_min) tv_min = t0, contour_entry = true;
          tv_max = std::fmin(tv_max, t1);
        }
      }
      if (tv_min <= tv_max) {
        // The slab's plane is the surface entered, at a leaf hit or for the subtree below.
        if (contour_entry) {
          entry_axis = 3;
          for (int a = 0; a < 3; ++a) entry_contour[a] = float(contour.normal[a]);
        }
        const bool leaf = (w0 >> octant & 1) == 0;
        if (leaf || (use_lod && tc_max * lod_coef + lod_bias >= scale_exp2)) {
          out.level = std::uint32_t(kMaxScale - scale);
          VoxelHit& hit = out.hit;
          hit.t = tv_min;
          const float n = float(frame_.resolution);
          const auto cells = std::uint32_t(frame_.resolution >> out.level);
          std::uint32_t cell[3];
          for (int a = 0; a < 3; ++a) {
            const float corner = (mirror >> a & 1) ? 3.0f - pos[a] - scale_exp2 : pos[a];
            const auto first = std::uint32_t((corner - 1.0f) * n);
            const float at = ((o[a] + tv_min * d[a]) - 1.0f) * n;
            const float rel = std::floor(at) - float(first);
            cell[a] = first + (rel < 0 ? 0 : rel >= float(cells) ? cells - 1 : std::uint32_t(rel));
          }
          hit.x = cell[0], hit.y = cell[1], hit.z = cell[2];
          if (entry_axis >= 0 && entry_axis < 3) {
            hit.face_normal[entry_axis] = d[entry_axis] > 0 ? -1.0f : 1.0f;
          } else if (entry_axis == 3) {
            const float dn =
                entry_contour[0] * d[0] + entry_contour[1] * d[1] + entry_contour[2] * d[2];
            const float length = std::sqrt(entry_contour[0] * entry_contour[0] +
                                           entry_contour[1] * entry_contour[1] +
                                           entry_contour[2] * entry_contour[2]);
            const float s = (dn > 0 ? -1.0f : 1.0f) / length;
            for (int a = 0; a < 3; ++a) hit.face_normal[a] = entry_contour[a] * s;
          }
          if constexpr (!kAnyHit) {
            const std::uint64_t attachment = attachment_index(parent, w0, w1, octant);
            format::decode_octahedral(normals_[attachment], hit.normal);
            if (!colors_.empty()) out.color = colors_[attachment];
          }
          return out;
        }
        // PUSH: descend into the child; its subtree is searched within [tv_min, tv_max].
        stack[scale] = {parent, t_max};
        parent = format::first_child_word(words_.data(), parent, w0) +
                 2 * format::rank_below(w0 & 0xFF, octant);
        idx = 0;
        --scale;
        scale_exp2 = half;
        for (int a = 0; a < 3; ++a)
          if (half * coef[a] + tc[a] > tv_min) idx ^= 1u << a, pos[a] += half;
        t_min = tv_min;
        t_max = tv_max;
        loaded = false;
        continue;
      }
    }

    // ADVANCE to the next sibling along the ray.
    std::uint32_t step = 0;
    for (int a = 0; a < 3; ++a)
      if (tc[a] <= tc_max) step |= 1u << a, pos[a] -= scale_exp2;
    t_min = tc_max;
    entry_axis = std::countr_zero(step | 8u);
    idx ^= step;
    if ((idx & step) != 0) {
      // POP: the highest differing bit of the stepped coordinates is the level left behind.
      std::uint32_t differing = 0;
      for (int a = 0; a < 3; ++a)
        if (step >> a & 1) differing |= bits_of(pos[a]) ^ bits_of(pos[a] + scale_exp2);
      scale = int(bits_of(float(differing)) >> 23) - 127;
      if (scale >= kMaxScale) break;
      scale_exp2 = float_of(std::uint32_t(scale - kMaxScale + 127) << 23);
      parent = stack[scale].parent;
      t_max = stack[scale].t_max;
      idx = 0;
      for (int a = 0; a < 3; ++a) {
        const std::uint32_t shifted = bits_of(pos[a]) >> scale;
        pos[a] = float_of(shifted << scale);
        idx |= (shifted & 1) << a;
      }
      loaded = false;
    }
  }
  return out;
}

EsvoHit EsvoView::intersect(const Ray& ray, const EsvoLod& lod) const {
  return cast<false, false>(ray, lod, nullptr);
}

EsvoHit EsvoView::intersect_counting(const Ray& ray, Cost& cost, const EsvoLod& lod) const {
  return cast<false, true>(ray, lod, &cost);
}

EsvoHit EsvoView::intersect_any(const Ray& ray, const EsvoLod& lod) const {
  return cast<true, false>(ray, lod, nullptr);
}

bool EsvoView::occluded(const Ray& ray, const EsvoLod& lod) const {
  return cast<true, false>(ray, lod, nullptr).hit.hit();
}

void trace_rays(const EsvoView& esvo, std::span<const Ray> rays, std::span<VoxelHit> hits,
                bool any_hit, unsigned threads, const EsvoLod& lod) {
  parallel_for_batched(rays.size(), kRaysPerTask, threads, [&](std::size_t i) {
    hits[i] = any_hit ? esvo.intersect_any(rays[i], lod).hit : esvo.intersect(rays[i], lod).hit;
  });
}

}  // namespace kiln
