// SBVH spatial splits (Stich, Friedrich, Dietrich 2009).
#include <algorithm>
#include <vector>

#include "bvh_splits.hpp"

namespace kiln {

namespace {

float coord(const format::Float3& p, int axis) {
  return axis == 0 ? p.x : axis == 1 ? p.y : p.z;
}

}  // namespace

void split_reference(const PrimRef& ref, int axis, float position, const Scene& scene,
                     format::Box3f& left, format::Box3f& right) {
  left = format::Box3f{};
  right = format::Box3f{};
  const auto& t = scene.triangles[ref.prim];
  const format::Float3 v[3] = {scene.positions[t.v[0]], scene.positions[t.v[1]],
                               scene.positions[t.v[2]]};
  for (int i = 0; i < 3; ++i) {
    const format::Float3& a = v[i];
    const format::Float3& b = v[(i + 1) % 3];
    const float pa = coord(a, axis), pb = coord(b, axis);
    if (pa <= position) left.grow(a);
    if (pa >= position) right.grow(a);
    if ((pa < position && pb > position) || (pb < position && pa > position)) {
      const float s = std::clamp((position - pa) / (pb - pa), 0.0f, 1.0f);
      format::Float3 p{a.x + (b.x - a.x) * s, a.y + (b.y - a.y) * s, a.z + (b.z - a.z) * s};
      if (axis == 0) p.x = position;
      if (axis == 1) p.y = position;
      if (axis == 2) p.z = position;
      left.grow(p);
      right.grow(p);
    }
  }
  // The reference may already be clipped: stay inside its box and on the plane's sides.
  format::at(left.max, axis) = std::min(format::at(left.max, axis), position);
  format::at(right.min, axis) = std::max(format::at(right.min, axis), position);
  left = format::Box3f::intersection(left, ref.box);
  right = format::Box3f::intersection(right, ref.box);
}

SpatialSplit find_spatial_split(std::span<const PrimRef> refs, const format::Box3f& node_box,
                                const Scene& scene, const BvhBuildOptions& options) {
  const float node_area = node_box.half_area();
  const std::uint32_t k = std::max<std::uint32_t>(2, options.bins);
  SpatialSplit best;
  if (node_area <= 0.0f) return best;
  std::vector<format::Box3f> bin_box(k), right_box(k);
  std::vector<std::size_t> enter(k), exit(k);
  for (int axis = 0; axis < 3; ++axis) {
    const float origin = format::at(node_box.min, axis);
    const float extent = format::at(node_box.max, axis) - origin;
    if (!(extent > 0.0f)) continue;
    const float width = extent / float(k);
    const float inv_width = float(k) / extent;
    auto bin_of = [&](float x) {
      return std::min<std::uint32_t>(k - 1,
                                     std::uint32_t(std::max(0.0f, (x - origin) * inv_width)));
    };
    auto plane = [&](std::uint32_t b) { return origin + width * float(b); };
    std::fill(bin_box.begin(), bin_box.end(), format::Box3f{});
    std::fill(enter.begin(), enter.end(), 0);
    std::fill(exit.begin(), exit.end(), 0);
    for (const auto& r : refs) {
      const std::uint32_t first = bin_of(format::at(r.box.min, axis));
      const std::uint32_t last = std::max(first, bin_of(format::at(r.box.max, axis)));
      PrimRef rest = r;
      for (std::uint32_t b = first; b < last; ++b) {
        format::Box3f l, rr;
        split_reference(rest, axis, plane(b + 1), scene, l, rr);
        bin_box[b].grow(l);
        rest.box = rr;
      }
      bin_box[last].grow(rest.box);
      enter[first] += 1;
      exit[last] += 1;
    }
    format::Box3f acc;
    std::size_t right_count = 0;
    std::vector<std::size_t> right_counts(k);
    for (std::uint32_t b = k; b-- > 1;) {
      acc.grow(bin_box[b]);
      right_box[b] = acc;
      right_count += exit[b];
      right_counts[b] = right_count;
    }
    format::Box3f left;
    std::size_t left_count = 0;
    for (std::uint32_t b = 0; b + 1 < k; ++b) {
      left.grow(bin_box[b]);
      left_count += enter[b];
      const std::size_t rc = right_counts[b + 1];
      if (left_count == 0 || rc == 0) continue;
      const float cost = options.traversal_cost + options.intersection_cost *
                                                      (left.half_area() * float(left_count) +
                                                       right_box[b + 1].half_area() * float(rc)) /
                                                      node_area;
      if (cost < best.cost) {
        best.cost = cost;
        best.axis = axis;
        best.position = plane(b + 1);
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
