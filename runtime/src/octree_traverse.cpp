// Front-to-back octree traversal, parametric as in Revelles, Urena & Lastra (2000), "An
// Efficient Parametric Algorithm for Octree Traversal": a cell carries, per axis, the distances
// t_near and t_far at which the ray crosses its slab; a child's are (t_near, t_mid) or
// (t_mid, t_far), where t_mid is the crossing of the centre plane, so only three distances are
// computed per node. Negative directions are mirrored (octant c ^ near_bits is the c-th along
// the ray), and a zero direction component gives (-inf, inf) on the origin's side of the centre.
//
// Instead of the paper's next-node table, the present children are ordered by entry distance
// (at most eight), pushed farthest first on a fixed stack, with every distance padded by its
// rounding error so that no cell the ray touches is culled (this may add cells the ray only
// grazes; they are harmless). Sibling cells share the very same centre-plane distance, so the
// cells' t-ranges tile the ray with no gap.
//
// Exactness: a triangle lives in every leaf whose cell it overlaps and a leaf tests whole
// triangles against the whole ray, keeping the closest hit over all tested; a cell is skipped
// only when it starts after the best hit so far (the paper's "stop when the best hit lies before
// the leaf's exit", applied to each waiting cell), so the hit found is the closest.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>

#include "kiln/runtime/octree.hpp"
#include "kiln/runtime/watertight.hpp"
#include "ray_box.hpp"

namespace kiln {

namespace {

constexpr float kNearScale = 2.0f - kFarScale;
constexpr float kInf = std::numeric_limits<float>::infinity();

// A distance moved outwards (up or down) by its rounding error.
float pad_up(float t) {
  return t < 0.0f ? t * kNearScale : t * kFarScale;
}
float pad_down(float t) {
  return t < 0.0f ? t * kFarScale : t * kNearScale;
}

struct OctRay {
  float org[3], inv_dir[3];
  bool flat[3];             // zero direction component
  std::uint32_t near_bits;  // bit a: the upper half on axis a comes first (negative direction)
  float tmin, tmax;
};

struct Frame {
  std::uint32_t node;
  float entry, exit;
  float lo[3], hi[3];
  float t_near[3], t_far[3];
};

OctRay prepare(const Ray& ray) {
  OctRay r{};
  const float org[3] = {ray.org.x, ray.org.y, ray.org.z};
  const float dir[3] = {ray.dir.x, ray.dir.y, ray.dir.z};
  for (int a = 0; a < 3; ++a) {
    r.org[a] = org[a];
    r.flat[a] = dir[a] == 0.0f;
    r.inv_dir[a] = r.flat[a] ? 0.0f : 1.0f / dir[a];
    r.near_bits |= dir[a] < 0.0f ? 1u << a : 0u;
  }
  r.tmin = ray.tmin, r.tmax = ray.tmax;
  return r;
}

// Entry and exit of a frame from its per-axis distances; false when the padded range is empty.
inline bool close_frame(const OctRay& r, Frame& f) {
  float entry = r.tmin, exit = r.tmax;
  for (int a = 0; a < 3; ++a) {
    entry = f.t_near[a] > entry ? f.t_near[a] : entry;
    exit = f.t_far[a] < exit ? f.t_far[a] : exit;
  }
  f.entry = entry, f.exit = exit;
  return pad_down(entry) <= pad_up(exit);
}

bool root_frame(const OctRay& r, const format::Box3f& b, Frame& f) {
  f.node = 0;
  for (int a = 0; a < 3; ++a) {
    f.lo[a] = format::at(b.min, a), f.hi[a] = format::at(b.max, a);
    if (r.flat[a]) {
      if (!(r.org[a] >= f.lo[a] && r.org[a] <= f.hi[a])) return false;
      f.t_near[a] = -kInf, f.t_far[a] = kInf;
      continue;
    }
    const float t_lo = (f.lo[a] - r.org[a]) * r.inv_dir[a];
    const float t_hi = (f.hi[a] - r.org[a]) * r.inv_dir[a];
    const bool negative = r.near_bits >> a & 1u;
    f.t_near[a] = negative ? t_hi : t_lo;
    f.t_far[a] = negative ? t_lo : t_hi;
  }
  return close_frame(r, f);
}

// Set bits of a byte (the library targets baseline x86-64, whose popcount is a library call).
constexpr auto kBitCount = [] {
  std::array<std::uint8_t, 256> table{};
  for (std::uint32_t i = 0; i < 256; ++i) table[i] = std::uint8_t(std::popcount(i));
  return table;
}();

// Pushes the children of `f` (interior node `n`) the ray enters before `limit` onto `stack`,
// farthest first, so the nearest is expanded next.
void push_children(const OctRay& r, const Frame& f, const format::OctreeNode& n, float limit,
                   Frame* stack, std::uint32_t& top) {
  const std::uint32_t mask = n.child_mask();
  // Per axis, the child's slab distances by its half (0 lower, 1 upper): the near half gets
  // (t_near, t_mid), the far one (t_mid, t_far); parallel to the axis, both (-inf, inf) but only
  // on the origin's side of the centre plane (both sides when on it).
  float mid[3], near_t[3][2], far_t[3][2];
  std::uint32_t allowed = mask;
  for (int a = 0; a < 3; ++a) {
    mid[a] = format::octree_mid(f.lo[a], f.hi[a]);
    if (r.flat[a]) {
      near_t[a][0] = near_t[a][1] = -kInf, far_t[a][0] = far_t[a][1] = kInf;
      const std::uint32_t upper = a == 0 ? 0xAAu : a == 1 ? 0xCCu : 0xF0u;
      if (r.org[a] < mid[a]) allowed &= ~upper;
      if (r.org[a] > mid[a]) allowed &= upper;
      continue;
    }
    const float t_mid = (mid[a] - r.org[a]) * r.inv_dir[a];
    const std::uint32_t near_half = r.near_bits >> a & 1u;
    near_t[a][near_half] = f.t_near[a], far_t[a][near_half] = t_mid;
    near_t[a][near_half ^ 1u] = t_mid, far_t[a][near_half ^ 1u] = f.t_far[a];
  }
  const float padded_limit = pad_up(limit);
  struct Candidate {
    float entry, exit;
    std::uint32_t octant;
  } order[8];
  int count = 0;
  for (std::uint32_t j = 0; j < 8; ++j) {
    const std::uint32_t c = j ^ r.near_bits;  // the j-th octant along the ray
    if ((allowed >> c & 1u) == 0) continue;
    const std::uint32_t x = c & 1u, y = c >> 1 & 1u, z = c >> 2 & 1u;
    const float entry =
        std::max(std::max(r.tmin, near_t[0][x]), std::max(near_t[1][y], near_t[2][z]));
    const float exit = std::min(std::min(r.tmax, far_t[0][x]), std::min(far_t[1][y], far_t[2][z]));
    if (pad_down(entry) > pad_up(exit) || pad_down(entry) > padded_limit) continue;
    int i = count++;
    for (; i > 0 && order[i - 1].entry > entry; --i) order[i] = order[i - 1];
    order[i] = {entry, exit, c};
  }
  for (int i = count; i-- > 0;) {
    const std::uint32_t c = order[i].octant;
    Frame& child = stack[top++];
    child.node = n.first_child() + kBitCount[mask & ((1u << c) - 1u)];
    child.entry = order[i].entry, child.exit = order[i].exit;
    for (int a = 0; a < 3; ++a) {
      const std::uint32_t upper = c >> a & 1u;
      child.lo[a] = upper ? mid[a] : f.lo[a];
      child.hi[a] = upper ? f.hi[a] : mid[a];
      child.t_near[a] = near_t[a][upper];
      child.t_far[a] = far_t[a][upper];
    }
  }
}

// The triangles tested last for this ray (Amanatides & Woo's mailbox, as a small ring): a
// triangle spanning neighbouring leaves is met again at once, and testing it again could not
// change the hit (its t is either the best already or not in range), so it is skipped.
struct Mailbox {
  std::uint32_t ids[8] = {kNoHit, kNoHit, kNoHit, kNoHit, kNoHit, kNoHit, kNoHit, kNoHit};
  std::uint32_t next = 0;
  // Whether `prim` was tested lately; records it otherwise.
  bool seen(std::uint32_t prim) {
    for (const std::uint32_t id : ids)
      if (id == prim) return true;
    ids[next++ & 7u] = prim;
    return false;
  }
};

template <bool kAnyHit, bool kCount>
Hit traverse(const OctreeView& tree, const Ray& ray, Cost* cost) {
  const OctRay r = prepare(ray);
  // Expanding a node replaces it by at most eight children: seven more per level.
  Frame stack[7 * format::kOctreeMaxDepth + 8];
  std::uint32_t top = 0;
  if (!root_frame(r, tree.bounds(), stack[top])) return Hit{};
  ++top;
  const auto nodes = tree.nodes();
  const auto prim_ids = tree.prim_ids();
  const auto triangles = tree.triangles();
  const WatertightRay tri_ray = prepare_watertight(ray);
  Hit hit;
  hit.t = ray.tmax;
  Mailbox recent;
  while (top > 0) {
    const Frame f = stack[--top];
    // Cells are skipped once they start after the best hit: nothing in them can be closer.
    if (pad_down(f.entry) > pad_up(hit.t)) continue;
    const format::OctreeNode n = nodes[f.node];
    if constexpr (kCount) cost->nodes += 1;
    if (!n.is_leaf()) {
      push_children(r, f, n, hit.t, stack, top);
      continue;
    }
    for (std::uint32_t i = n.first_reference(), end = i + n.reference_count(); i < end; ++i) {
      const std::uint32_t prim = prim_ids[i];
      if (recent.seen(prim)) continue;
      if constexpr (kCount) cost->tests += 1;
      const format::RayTriangle& tri = triangles[prim];
      float t, u, v;
      if (intersect_watertight(tri_ray, tri.v0, tri.v1, tri.v2, ray.tmin, hit.t, t, u, v)) {
        hit = {t, prim, u, v};
        if constexpr (kAnyHit) return hit;
      }
    }
  }
  if (hit.prim == kNoHit) return Hit{};
  return hit;
}

}  // namespace

void octree_leaves_along(const OctreeView& tree, const Ray& ray,
                         const std::function<void(std::uint32_t, float, float)>& visit) {
  const OctRay r = prepare(ray);
  Frame stack[7 * format::kOctreeMaxDepth + 8];
  std::uint32_t top = 0;
  if (!root_frame(r, tree.bounds(), stack[top])) return;
  ++top;
  while (top > 0) {
    const Frame f = stack[--top];
    const format::OctreeNode n = tree.nodes()[f.node];
    if (n.is_leaf()) {
      visit(f.node, f.entry, f.exit);
      continue;
    }
    push_children(r, f, n, ray.tmax, stack, top);
  }
}

Hit OctreeView::intersect(const Ray& ray) const {
  return traverse<false, false>(*this, ray, nullptr);
}

Hit OctreeView::intersect_counting(const Ray& ray, Cost& cost) const {
  return traverse<false, true>(*this, ray, &cost);
}

Hit OctreeView::intersect_any(const Ray& ray) const {
  return traverse<true, false>(*this, ray, nullptr);
}

bool OctreeView::occluded(const Ray& ray) const {
  return traverse<true, false>(*this, ray, nullptr).hit();
}

}  // namespace kiln
