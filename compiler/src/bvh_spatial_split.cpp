// SBVH spatial splits (Stich, Friedrich, Dietrich 2009).
#include <algorithm>
#include <vector>

#include "bvh_splits.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln {

namespace {

constexpr std::size_t kParallelSpatial = 32768;  // bin the three axes apart above this

float coord(const format::Float3& p, int axis) {
  return axis == 0 ? p.x : axis == 1 ? p.y : p.z;
}

// split_reference on a triangle's corners already loaded: the spatial binning clips one
// reference at every plane it crosses, and loads its corners once for all of them.
// Local boxes, written out once: growing the caller's boxes through references kept them in
// memory (a store and a reload per coordinate).
[[gnu::always_inline]] inline void split_corners(const format::Float3 (&v)[3],
                                                 const format::Box3f& ref_box, int axis,
                                                 float position, format::Box3f& left_out,
                                                 format::Box3f& right_out) {
  format::Box3f left, right;
  for (int i = 0; i < 3; ++i) {
    const format::Float3& a = v[i];
    const format::Float3& b = v[i == 2 ? 0 : i + 1];
    const float pa = coord(a, axis), pb = coord(b, axis);
    if (pa <= position) left.grow(a);
    if (pa >= position) right.grow(a);
    if ((pa < position && pb > position) || (pb < position && pa > position)) {
      const float s = std::clamp((position - pa) / (pb - pa), 0.0f, 1.0f);
      format::Float3 p{a.x + (b.x - a.x) * s, a.y + (b.y - a.y) * s, a.z + (b.z - a.z) * s};
      format::at(p, axis) = position;
      left.grow(p);
      right.grow(p);
    }
  }
  // The reference may already be clipped: stay inside its box and on the plane's sides.
  format::at(left.max, axis) = std::min(format::at(left.max, axis), position);
  format::at(right.min, axis) = std::max(format::at(right.min, axis), position);
  left_out = format::Box3f::intersection(left, ref_box);
  right_out = format::Box3f::intersection(right, ref_box);
}

void load_corners(const PrimRef& ref, const Scene& scene, format::Float3 (&v)[3]) {
  const auto& t = scene.triangles[ref.prim];
  for (int i = 0; i < 3; ++i) v[i] = scene.positions[t.v[i]];
}

}  // namespace

void split_reference(const PrimRef& ref, int axis, float position, const Scene& scene,
                     format::Box3f& left, format::Box3f& right) {
  format::Float3 v[3];
  load_corners(ref, scene, v);
  split_corners(v, ref.box, axis, position, left, right);
}

namespace {

/// Spatial bins on the three axes over a node box: the planes, each bin's box of clipped pieces,
/// and how many references enter (start) and exit (end) in each bin.
struct SpatialBins {
  std::uint32_t k;
  float origin[3], width[3], inv_width[3];
  bool valid[3];
  std::vector<format::Box3f> box;  // axis-major
  std::vector<std::size_t> enter, exit;

  SpatialBins(const format::Box3f& node_box, std::uint32_t bins)
      : k(bins), box(3 * std::size_t(k)), enter(3 * std::size_t(k)), exit(3 * std::size_t(k)) {
    for (int a = 0; a < 3; ++a) {
      origin[a] = format::at(node_box.min, a);
      const float extent = format::at(node_box.max, a) - origin[a];
      valid[a] = extent > 0.0f;
      width[a] = extent / float(k);
      inv_width[a] = float(k) / extent;
    }
  }
  std::uint32_t bin_of(int a, float x) const {
    return std::min<std::uint32_t>(k - 1,
                                   std::uint32_t(std::max(0.0f, (x - origin[a]) * inv_width[a])));
  }
  float plane(int a, std::uint32_t b) const { return origin[a] + width[a] * float(b); }

  // Clips the reference at every bin plane it crosses on axis a, growing each bin by its piece.
  void add(const PrimRef& r, const format::Float3 (&v)[3], int a) {
    const std::size_t base = std::size_t(a) * k;
    const std::uint32_t first = bin_of(a, format::at(r.box.min, a));
    const std::uint32_t last = std::max(first, bin_of(a, format::at(r.box.max, a)));
    format::Box3f rest = r.box;
    for (std::uint32_t b = first; b < last; ++b) {
      format::Box3f l, rr;
      split_corners(v, rest, a, plane(a, b + 1), l, rr);
      box[base + b].grow(l);
      rest = rr;
    }
    box[base + last].grow(rest);
    enter[base + first] += 1;
    exit[base + last] += 1;
  }
};

}  // namespace

SpatialSplit find_spatial_split(std::span<const PrimRef> refs, const format::Box3f& node_box,
                                const Scene& scene, const BvhBuildOptions& options) {
  const float node_area = node_box.half_area();
  const std::uint32_t k = std::max<std::uint32_t>(2, options.bins);
  SpatialSplit best;
  if (node_area <= 0.0f) return best;
  // Reference by reference (its corners loaded once), each axis's bins in reference order as
  // before: the same boxes, the same split. A large node (near the root, where the subtree
  // tasks have not forked yet) bins its three axes on their own threads, each into its own bins.
  SpatialBins bins(node_box, k);
  if (refs.size() >= kParallelSpatial && resolve_thread_count(options.threads) > 1) {
    parallel_for(3, options.threads, [&](std::size_t a) {
      if (!bins.valid[a]) return;
      for (const auto& r : refs) {
        format::Float3 v[3];
        load_corners(r, scene, v);
        bins.add(r, v, int(a));
      }
    });
  } else {
    for (const auto& r : refs) {
      format::Float3 v[3];
      load_corners(r, scene, v);
      for (int a = 0; a < 3; ++a)
        if (bins.valid[a]) bins.add(r, v, a);
    }
  }
  std::vector<format::Box3f> right_box(k);
  std::vector<std::size_t> right_counts(k);
  for (int axis = 0; axis < 3; ++axis) {
    if (!bins.valid[axis]) continue;
    const std::size_t base = std::size_t(axis) * k;
    format::Box3f acc;
    std::size_t right_count = 0;
    for (std::uint32_t b = k; b-- > 1;) {
      acc.grow(bins.box[base + b]);
      right_box[b] = acc;
      right_count += bins.exit[base + b];
      right_counts[b] = right_count;
    }
    format::Box3f left;
    std::size_t left_count = 0;
    for (std::uint32_t b = 0; b + 1 < k; ++b) {
      left.grow(bins.box[base + b]);
      left_count += bins.enter[base + b];
      const std::size_t rc = right_counts[b + 1];
      if (left_count == 0 || rc == 0) continue;
      const float cost = options.traversal_cost + options.intersection_cost *
                                                      (left.half_area() * float(left_count) +
                                                       right_box[b + 1].half_area() * float(rc)) /
                                                      node_area;
      if (cost < best.cost) {
        best.cost = cost;
        best.axis = axis;
        best.position = bins.plane(axis, b + 1);
      }
    }
  }
  return best;
}

std::size_t apply_spatial_split(const SpatialSplit& split, std::span<const PrimRef> refs,
                                const Scene& scene, std::vector<PrimRef>& left,
                                std::vector<PrimRef>& right) {
  const int axis = split.axis;
  const float pos = split.position;
  format::Box3f left_box, right_box;
  std::vector<const PrimRef*> straddling;
  for (const auto& r : refs) {
    if (format::at(r.box.max, axis) <= pos) {
      left.push_back(r);
      left_box.grow(r.box);
    } else if (format::at(r.box.min, axis) >= pos) {
      right.push_back(r);
      right_box.grow(r.box);
    } else {
      straddling.push_back(&r);
    }
  }
  std::size_t left_count = left.size() + straddling.size();
  std::size_t right_count = right.size() + straddling.size();
  std::size_t added = 0;
  for (const PrimRef* r : straddling) {
    format::Box3f l, rr;
    split_reference(*r, axis, pos, scene, l, rr);
    if (l.empty()) {  // clipping left nothing on one side: no duplicate needed
      right.push_back(*r);
      right_box.grow(r->box);
      left_count -= 1;
      continue;
    }
    if (rr.empty()) {
      left.push_back(*r);
      left_box.grow(r->box);
      right_count -= 1;
      continue;
    }
    // Reference unsplitting: keep the whole reference on one side when that is cheaper.
    format::Box3f split_l = left_box, split_r = right_box;
    split_l.grow(l);
    split_r.grow(rr);
    format::Box3f whole_l = left_box, whole_r = right_box;
    whole_l.grow(r->box);
    whole_r.grow(r->box);
    const float c_split =
        split_l.half_area() * float(left_count) + split_r.half_area() * float(right_count);
    const float c_left =
        whole_l.half_area() * float(left_count) + right_box.half_area() * float(right_count - 1);
    const float c_right =
        left_box.half_area() * float(left_count - 1) + whole_r.half_area() * float(right_count);
    if (c_left < c_split && c_left <= c_right) {
      left.push_back(*r);
      left_box = whole_l;
      right_count -= 1;
    } else if (c_right < c_split) {
      right.push_back(*r);
      right_box = whole_r;
      left_count -= 1;
    } else {
      left.push_back({l, r->prim});
      right.push_back({rr, r->prim});
      left_box = split_l;
      right_box = split_r;
      added += 1;
    }
  }
  return added;
}

}  // namespace kiln
