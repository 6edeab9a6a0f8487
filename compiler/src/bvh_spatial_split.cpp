// SBVH spatial splits (Stich, Friedrich, Dietrich 2009).
#include <algorithm>
#include <limits>
#include <utility>
#include <vector>

#include "bvh_build_simd.hpp"
#include "bvh_splits.hpp"
#include "huge_pages.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln {

namespace {

constexpr std::size_t kParallelSpatial = 32768;  // bin in chunks (in parallel) above this
constexpr std::size_t kSpatialChunk = 8192;

float coord(const format::Float3& p, int axis) {
  return axis == 0 ? p.x : axis == 1 ? p.y : p.z;
}

// The point where the edge a-b crosses the plane axis = position (strictly between its ends).
[[gnu::always_inline]] inline format::Float3 edge_point(const format::Float3& a,
                                                        const format::Float3& b, float pa, float pb,
                                                        int axis, float position) {
  const float s = std::clamp((position - pa) / (pb - pa), 0.0f, 1.0f);
  format::Float3 p{a.x + (b.x - a.x) * s, a.y + (b.y - a.y) * s, a.z + (b.z - a.z) * s};
  format::at(p, axis) = position;
  return p;
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
      const format::Float3 p = edge_point(a, b, pa, pb, axis, position);
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

/// Spatial bins on the three axes over a node box: the planes, each bin's box of clipped pieces
/// (two vectors per bin, min x y z and max x y z, the fourth lanes unused) and how many
/// references enter (start) and exit (end) in each bin.
struct SpatialBins {
  std::uint32_t k;
  float origin[3], width[3], inv_width[3];
  bool valid[3];
  std::vector<float> bounds;  // [axis][bin]: min x y z -, max x y z -
  std::vector<std::size_t> enter, exit;

  SpatialBins(const format::Box3f& node_box, std::uint32_t bins)
      : k(bins), bounds(24 * std::size_t(k)), enter(3 * std::size_t(k)), exit(3 * std::size_t(k)) {
    constexpr float kInf = std::numeric_limits<float>::infinity();
    for (int a = 0; a < 3; ++a) {
      origin[a] = format::at(node_box.min, a);
      const float extent = format::at(node_box.max, a) - origin[a];
      valid[a] = extent > 0.0f;
      width[a] = extent / float(k);
      inv_width[a] = float(k) / extent;
    }
    for (std::size_t i = 0; i < bounds.size(); i += 8) {
      std::fill_n(bounds.data() + i, 4, kInf);
      std::fill_n(bounds.data() + i + 4, 4, -kInf);
    }
  }
  float* at(int a, std::uint32_t b) { return bounds.data() + (std::size_t(a) * k + b) * 8; }
  const float* at(int a, std::uint32_t b) const {
    return bounds.data() + (std::size_t(a) * k + b) * 8;
  }
  format::Box3f box(int a, std::uint32_t b) const {
    const float* x = at(a, b);
    return {{x[0], x[1], x[2]}, {x[4], x[5], x[6]}};
  }
  // Box3f::grow's operations and operand order, on vectors.
  [[gnu::always_inline]] void grow(int a, std::uint32_t b, bvh_simd::V4 lo, bvh_simd::V4 hi) {
    using namespace bvh_simd;
    float* x = at(a, b);
    storeu(x, vmin(lo, loadu(x)));
    storeu(x + 4, vmax(hi, loadu(x + 4)));
  }
  std::uint32_t bin_of(int a, float x) const {
    return std::min<std::uint32_t>(k - 1,
                                   std::uint32_t(std::max(0.0f, (x - origin[a]) * inv_width[a])));
  }
  float plane(int a, std::uint32_t b) const { return origin[a] + width[a] * float(b); }

  // The bins a reference's box spans on axis a.
  [[gnu::always_inline]] std::pair<std::uint32_t, std::uint32_t> span_of(const PrimRef& r,
                                                                         int a) const {
    const std::uint32_t first = bin_of(a, format::at(r.box.min, a));
    return {first, std::max(first, bin_of(a, format::at(r.box.max, a)))};
  }

  // Counts the reference's entry and exit on axis a. One inside a single bin grows it by its box
  // and is done; for one that crosses a plane, true: its pieces are still to add (clip).
  [[gnu::always_inline]] bool count(const PrimRef& r, int a) {
    const auto [first, last] = span_of(r, a);
    enter[std::size_t(a) * k + first] += 1;
    exit[std::size_t(a) * k + last] += 1;
    // A PrimRef's box is min x y z, max x y z, prim: four floats from each corner stay in it.
    if (first == last) grow(a, first, bvh_simd::loadu(&r.box.min.x), bvh_simd::loadu(&r.box.max.x));
    return first != last;
  }

  // Whether every bin the reference crosses on axis a already holds the reference's box cut to
  // the bin's slab: each clipped piece lies in that box (add_slabs ends by clamping to the slab
  // and the reference's box), so clipping could not change a bit of these bins.
  [[gnu::always_inline]] bool covers(const PrimRef& r, int a) const {
    using namespace bvh_simd;
    constexpr float kInf = std::numeric_limits<float>::infinity();
    const auto [first, last] = span_of(r, a);
    const V4 on_axis = lt(splat(0.0f), set(a == 0, a == 1, a == 2, 0));  // lane a set
    const V4 rmin = loadu(&r.box.min.x), rmax = loadu(&r.box.max.x);
    for (std::uint32_t b = first; b <= last; ++b) {
      const V4 lo = blend(on_axis, splat(b > first ? plane(a, b) : -kInf), splat(-kInf));
      const V4 hi = blend(on_axis, splat(b < last ? plane(a, b + 1) : kInf), splat(kInf));
      const float* x = at(a, b);
      if (mask_bits(lt(vmax(lo, rmin), loadu(x)) | lt(loadu(x + 4), vmin(hi, rmax))) & 7)
        return false;
    }
    return true;
  }

  // Grows every bin that the reference crosses on axis a by the box of its triangle's part in
  // that bin's slab (within the reference's box). Each plane's cut through the triangle is
  // computed once and serves the bins on both sides; the slab boxes are exact, as the sides
  // apply_spatial_split makes, where clipping the rest at each plane in turn (as Stich et al.
  // and Embree do) gives the intersection of two half-space boxes, larger in general.
  [[gnu::always_inline]] void clip(const PrimRef& r, const format::Float3 (&v)[3], int a) {
    const auto [first, last] = span_of(r, a);
    add_slabs(r, v, a, first, last);
  }

  // clip's pieces, bin by bin on x y z vectors: each plane's cut (the points where the edges
  // cross it) once, each bin's box from its lower and upper cuts and the corners between its
  // planes. Every lane computes what the scalar clipping did, operation for operation (the same
  // bits), and min/max keep Box3f::grow's and intersection's operand order.
  [[gnu::always_inline]] inline void add_slabs(const PrimRef& r, const format::Float3 (&v)[3],
                                               int a, std::uint32_t first, std::uint32_t last);
};

// The box of the points where a triangle's edges cross the plane axis a = h (empty where none
// does): edge_point's operations on x y z vectors (corners p, their axis coordinates c; lane a
// of `on_axis` set).
[[gnu::always_inline]] inline void plane_cut(const bvh_simd::V4 (&p)[3], const float (&c)[3],
                                             bvh_simd::V4 on_axis, float h, bvh_simd::V4& cut_min,
                                             bvh_simd::V4& cut_max) {
  using namespace bvh_simd;
  constexpr float kInf = std::numeric_limits<float>::infinity();
  cut_min = splat(kInf), cut_max = splat(-kInf);
  for (int i = 0; i < 3; ++i) {
    const int j = i == 2 ? 0 : i + 1;
    // Without a branch (whether an edge crosses is hard to predict); an edge that does not
    // cross may divide by zero, and its point is dropped.
    const bool cross = ((c[i] < h) & (h < c[j])) | ((c[j] < h) & (h < c[i]));
    const V4 s = vmin(splat(1.0f), vmax(splat(0.0f), splat((h - c[i]) / (c[j] - c[i]))));
    const V4 x = blend(on_axis, splat(h), p[i] + (p[j] - p[i]) * s);
    cut_min = vmin(select(cross, x, splat(kInf)), cut_min);
    cut_max = vmax(select(cross, x, splat(-kInf)), cut_max);
  }
}

inline void SpatialBins::add_slabs(const PrimRef& r, const format::Float3 (&v)[3], int a,
                                   std::uint32_t first, std::uint32_t last) {
  using namespace bvh_simd;
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const V4 inf = splat(kInf), ninf = splat(-kInf);
  const V4 on_axis = lt(splat(0.0f), set(a == 0, a == 1, a == 2, 0));  // lane a set
  V4 p[3];
  float c[3];
  for (int i = 0; i < 3; ++i) p[i] = set(v[i].x, v[i].y, v[i].z, 0.0f), c[i] = format::at(v[i], a);
  const V4 rmin = loadu(&r.box.min.x), rmax = loadu(&r.box.max.x);
  float lo = -kInf;
  V4 lo_cut_min = inf, lo_cut_max = ninf;  // the cut at lo (none below the first bin)
  for (std::uint32_t b = first; b <= last; ++b) {
    const float hi = b < last ? plane(a, b + 1) : kInf;  // the last bin has no upper plane
    V4 hi_cut_min = inf, hi_cut_max = ninf;
    if (b < last) plane_cut(p, c, on_axis, hi, hi_cut_min, hi_cut_max);
    V4 box_min = lo_cut_min, box_max = lo_cut_max;
    for (int i = 0; i < 3; ++i) {
      const bool in = lo <= c[i] && c[i] <= hi;
      box_min = vmin(select(in, p[i], inf), box_min);
      box_max = vmax(select(in, p[i], ninf), box_max);
    }
    box_min = vmin(hi_cut_min, box_min);
    box_max = vmax(hi_cut_max, box_max);
    box_min = vmax(blend(on_axis, splat(lo), ninf), box_min);
    box_max = vmin(blend(on_axis, splat(hi), inf), box_max);
    box_min = vmax(rmin, box_min);
    box_max = vmin(rmax, box_max);
    if ((mask_bits(lt(box_max, box_min)) & 7) == 0) grow(a, b, box_min, box_max);
    lo = hi, lo_cut_min = hi_cut_min, lo_cut_max = hi_cut_max;
  }
}

}  // namespace

namespace {

// A reference that crosses a bin plane on some axis: its index and a bit per such axis.
struct Straddler {
  std::uint32_t index;
  std::uint32_t axes;
};

// The first of spatial binning's two passes, on every axis with extent: counts every reference
// from its box alone, grows the bins of those inside one bin (most of a large node's
// references) and lists the others, whose triangles are clipped only if a plane may pay.
void count_references(std::span<const PrimRef> refs, SpatialBins& bins,
                      std::vector<Straddler>& straddlers) {
  straddlers.clear();
  for (std::size_t i = 0; i < refs.size(); ++i) {
    std::uint32_t axes = 0;
    for (int a = 0; a < 3; ++a)
      if (bins.valid[a] && bins.count(refs[i], a)) axes |= 1u << a;
    if (axes != 0) straddlers.push_back({std::uint32_t(i), axes});
  }
}

// The second pass: the listed references' pieces, their corners loaded once for all axes.
[[gnu::always_inline]] inline void clip_each(std::span<const PrimRef> refs,
                                             std::span<const Straddler> straddlers,
                                             const Scene& scene, SpatialBins& bins) {
  // The triangles and corners are scattered over the scene: prefetched, the triangle
  // kTriangleAhead straddlers ahead, its corners kCornersAhead ahead.
  constexpr std::size_t kTriangleAhead = 16, kCornersAhead = 8;
  const std::size_t n = straddlers.size();
  for (std::size_t s = 0; s < n; ++s) {
    if (s + kTriangleAhead < n)
      __builtin_prefetch(&scene.triangles[refs[straddlers[s + kTriangleAhead].index].prim]);
    if (s + kCornersAhead < n)
      for (const auto v : scene.triangles[refs[straddlers[s + kCornersAhead].index].prim].v)
        __builtin_prefetch(&scene.positions[v]);
    const PrimRef& r = refs[straddlers[s].index];
    std::uint32_t axes = straddlers[s].axes;
    for (int a = 0; a < 3; ++a)
      if ((axes >> a & 1) && bins.covers(r, a)) axes &= ~(1u << a);
    if (axes == 0) continue;  // nothing to clip: its corners are not even loaded
    format::Float3 v[3];
    load_corners(r, scene, v);
    for (int a = 0; a < 3; ++a)
      if (axes >> a & 1) bins.clip(r, v, a);
  }
}

void clip_references_sse(std::span<const PrimRef> refs, std::span<const Straddler> straddlers,
                         const Scene& scene, SpatialBins& bins) {
  clip_each(refs, straddlers, scene, bins);
}

#if (defined(__x86_64__) || defined(__i386__)) && defined(__GNUC__)
#define KILN_SPATIAL_EVEX 1
// The same code, operation for operation, in EVEX encodings: AVX-512VL's 32 vector registers
// hold the corners, cuts and boxes, which spill on SSE's 16. Still four lanes, and no FMA (the
// project builds with -ffp-contract=off), so the bins are the same bits.
__attribute__((target("avx2,avx512f,avx512vl"))) void clip_references_evex(
    std::span<const PrimRef> refs, std::span<const Straddler> straddlers, const Scene& scene,
    SpatialBins& bins) {
  clip_each(refs, straddlers, scene, bins);
}
#endif

void clip_references(std::span<const PrimRef> refs, std::span<const Straddler> straddlers,
                     const Scene& scene, SpatialBins& bins) {
#if defined(KILN_SPATIAL_EVEX)
  static const bool evex = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl");
  if (evex) return clip_references_evex(refs, straddlers, scene, bins);
#endif
  clip_references_sse(refs, straddlers, scene, bins);
}

// Bin boxes grow by min/max and counts add, so merging chunks in any order gives the same bins.
void merge_bins(SpatialBins& into, const SpatialBins& from) {
  for (int a = 0; a < 3; ++a)
    for (std::uint32_t b = 0; b < into.k; ++b)
      into.grow(a, b, bvh_simd::loadu(from.at(a, b)), bvh_simd::loadu(from.at(a, b) + 4));
  for (std::size_t i = 0; i < into.enter.size(); ++i) {
    into.enter[i] += from.enter[i];
    into.exit[i] += from.exit[i];
  }
}

// The SAH sweep over one axis's bins; a cheaper plane replaces `best` (first axis, first plane
// win ties).
void best_plane_on_axis(const SpatialBins& bins, int axis, float node_area,
                        const BvhBuildOptions& options, SpatialSplit& best) {
  const std::uint32_t k = bins.k;
  thread_local std::vector<format::Box3f> right_box;
  thread_local std::vector<std::size_t> right_counts;
  right_box.resize(k);
  right_counts.resize(k);
  const std::size_t base = std::size_t(axis) * k;
  format::Box3f acc;
  std::size_t right_count = 0;
  for (std::uint32_t b = k; b-- > 1;) {
    acc.grow(bins.box(axis, b));
    right_box[b] = acc;
    right_count += bins.exit[base + b];
    right_counts[b] = right_count;
  }
  format::Box3f left;
  std::size_t left_count = 0;
  for (std::uint32_t b = 0; b + 1 < k; ++b) {
    left.grow(bins.box(axis, b));
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

}  // namespace

std::uint32_t spatial_bin_count(std::size_t refs, std::uint32_t bins) {
  const std::uint32_t k = std::max<std::uint32_t>(2, bins);
  if (refs >= kFineSpatialRefs) return 2 * k;
  if (refs >= kCoarseSpatialRefs) return k;
  return std::max<std::uint32_t>(2, k / 8);
}

unsigned spatial_axes(const format::Box3f& node_box, int object_axis) {
  int longest = 0;
  for (int a = 1; a < 3; ++a)
    if (format::at(node_box.max, a) - format::at(node_box.min, a) >
        format::at(node_box.max, longest) - format::at(node_box.min, longest))
      longest = a;
  return (1u << longest) | (object_axis >= 0 ? 1u << object_axis : 0u);
}

namespace {

// Whether some plane may cost less than `to_beat`, judged on bins that hold counts and the
// boxes of unclipped references only. Their boxes lie inside the full bins' (the clipped pieces
// only add to them) and the counts are exact, and the SAH sweep's arithmetic grows with the
// areas (round to nearest is monotone; an empty box has area 0). So its cost is a lower bound
// of every plane's: where it is not below `to_beat`, clipping cannot find a cheaper plane.
bool may_beat(const SpatialBins& bins, float node_area, const BvhBuildOptions& options,
              float to_beat) {
  SpatialSplit lower;
  for (int axis = 0; axis < 3; ++axis)
    if (bins.valid[axis]) best_plane_on_axis(bins, axis, node_area, options, lower);
  return lower.cost < to_beat;
}

// Both passes in fixed chunks (by count, not by thread), each into its own bins, merged: the
// same bins on any number of threads.
bool bin_in_chunks(std::span<const PrimRef> refs, const format::Box3f& node_box, const Scene& scene,
                   const BvhBuildOptions& options, float to_beat, unsigned threads,
                   SpatialBins& bins) {
  const std::size_t chunks = (refs.size() + kSpatialChunk - 1) / kSpatialChunk;
  const auto chunk = [&](std::size_t c) {
    return refs.subspan(c * kSpatialChunk,
                        std::min(kSpatialChunk, refs.size() - c * kSpatialChunk));
  };
  std::vector<SpatialBins> part(chunks, bins);
  std::vector<std::vector<Straddler>> straddlers(chunks);
  parallel_for(chunks, threads,
               [&](std::size_t c) { count_references(chunk(c), part[c], straddlers[c]); });
  for (const auto& p : part) merge_bins(bins, p);
  if (!may_beat(bins, node_box.half_area(), options, to_beat)) return false;
  const SpatialBins empty(node_box, bins.k);  // boxes only: the counts are in `bins`
  std::fill(part.begin(), part.end(), empty);
  parallel_for(chunks, threads,
               [&](std::size_t c) { clip_references(chunk(c), straddlers[c], scene, part[c]); });
  for (const auto& p : part) merge_bins(bins, p);
  return true;
}

}  // namespace

SpatialSplit find_spatial_split(std::span<const PrimRef> refs, const format::Box3f& node_box,
                                const Scene& scene, const BvhBuildOptions& options, int object_axis,
                                unsigned threads, float to_beat) {
  const float node_area = node_box.half_area();
  const std::uint32_t k = spatial_bin_count(refs.size(), options.bins);
  SpatialSplit best;
  if (node_area <= 0.0f || refs.size() < kMinSpatialRefs) return best;
  SpatialBins bins(node_box, k);
  const unsigned axes = spatial_axes(node_box, object_axis);
  for (int a = 0; a < 3; ++a) bins.valid[a] = bins.valid[a] && (axes >> a & 1);
  if (refs.size() >= kParallelSpatial) {
    if (!bin_in_chunks(refs, node_box, scene, options, to_beat, threads, bins)) return best;
  } else {
    thread_local std::vector<Straddler> straddlers;
    count_references(refs, bins, straddlers);
    if (!may_beat(bins, node_area, options, to_beat)) return best;
    clip_references(refs, straddlers, scene, bins);
  }
  for (int axis = 0; axis < 3; ++axis)
    if (bins.valid[axis]) best_plane_on_axis(bins, axis, node_area, options, best);
  return best;
}

namespace {

enum class Side : std::uint8_t { kLeft, kRight, kStraddle };

Side side_of(const PrimRef& r, int axis, float pos) {
  if (format::at(r.box.max, axis) <= pos) return Side::kLeft;
  if (format::at(r.box.min, axis) >= pos) return Side::kRight;
  return Side::kStraddle;
}

// `sorted` (sorted on `axis`) merged with `pieces` (sorted apart) into `out`, each key
// computed once.
void merge_on_axis(std::span<const PrimRef> sorted, std::span<const PrimRef> pieces, int axis,
                   std::vector<PrimRef>& out) {
  reserve_huge(out, sorted.size() + pieces.size());
  out.resize(sorted.size() + pieces.size());
  PrimRef* o = out.data();
  std::size_t i = 0, j = 0;
  if (!pieces.empty()) {
    std::uint64_t piece_key = centroid_key(pieces[0], axis);
    for (; i < sorted.size() && j < pieces.size(); ++i) {
      const std::uint64_t key = centroid_key(sorted[i], axis);
      while (piece_key < key) {
        *o++ = pieces[j++];
        if (j == pieces.size()) break;
        piece_key = centroid_key(pieces[j], axis);
      }
      *o++ = sorted[i];
    }
  }
  o = std::copy(sorted.begin() + std::ptrdiff_t(i), sorted.end(), o);
  std::copy(pieces.begin() + std::ptrdiff_t(j), pieces.end(), o);
}

// The children's arrays on `axis`: the references that stay whole on a side, in the parent's
// order (still sorted), merged with the straddlers' pieces (or whole references) given to that
// side, sorted apart: a straddler's clipped box moves its centroid.
// The children's array on `axis` from the parent's. The left child's is written into the parent's
// block: it holds at most as many references (a straddler goes to a side whole or as one piece
// each), and its pages are touched already, where a new block's would be faulted in (most of
// the page faults of the SBVH's spatial splits).
void children_on_axis(std::vector<PrimRef>& parent, int axis, int split_axis, float pos,
                      std::span<const PrimRef> left_straddlers,
                      std::span<const PrimRef> right_straddlers, std::vector<PrimRef>& left,
                      std::vector<PrimRef>& right) {
  thread_local std::vector<PrimRef> whole_left, whole_right, pieces;
  whole_left.clear();
  whole_right.clear();
  for (const PrimRef& r : parent) {
    const Side side = side_of(r, split_axis, pos);
    if (side == Side::kLeft) whole_left.push_back(r);
    if (side == Side::kRight) whole_right.push_back(r);
  }
  sort_by_centroid(left_straddlers, axis, pieces);
  merge_on_axis(whole_left, pieces, axis, parent);
  left = std::move(parent);
  sort_by_centroid(right_straddlers, axis, pieces);
  merge_on_axis(whole_right, pieces, axis, right);
}

// The references that lie whole on a side of the plane (their boxes and counts), and the
// straddlers in order, each with its two clipped boxes.
struct Sides {
  format::Box3f left_box, right_box;
  std::size_t left_whole = 0, right_whole = 0;
  std::vector<const PrimRef*> straddling;
  std::vector<std::pair<format::Box3f, format::Box3f>> clipped;  // [straddler]: left, right
};

void classify(std::span<const PrimRef> refs, int axis, float pos, const Scene& scene, Sides& out) {
  for (const auto& r : refs) {
    switch (side_of(r, axis, pos)) {
      case Side::kLeft:
        out.left_box.grow(r.box), ++out.left_whole;
        break;
      case Side::kRight:
        out.right_box.grow(r.box), ++out.right_whole;
        break;
      case Side::kStraddle:
        out.straddling.push_back(&r);
        auto& [l, rr] = out.clipped.emplace_back();
        split_reference(r, axis, pos, scene, l, rr);
    }
  }
}

// classify in fixed chunks on up to `threads` threads, merged in order: boxes grow by min/max,
// which keeps the first of equal bounds either way, so the result is one pass's.
Sides classify_all(std::span<const PrimRef> refs, int axis, float pos, const Scene& scene,
                   unsigned threads) {
  Sides all;
  if (threads == 1 || refs.size() < kParallelSweep) {
    classify(refs, axis, pos, scene, all);
    return all;
  }
  const std::size_t chunks = (refs.size() + kSpatialChunk - 1) / kSpatialChunk;
  std::vector<Sides> part(chunks);
  parallel_for(chunks, threads, [&](std::size_t c) {
    const std::size_t begin = c * kSpatialChunk;
    classify(refs.subspan(begin, std::min(kSpatialChunk, refs.size() - begin)), axis, pos, scene,
             part[c]);
  });
  for (const Sides& p : part) {
    all.left_box.grow(p.left_box), all.right_box.grow(p.right_box);
    all.left_whole += p.left_whole, all.right_whole += p.right_whole;
    all.straddling.insert(all.straddling.end(), p.straddling.begin(), p.straddling.end());
    all.clipped.insert(all.clipped.end(), p.clipped.begin(), p.clipped.end());
  }
  return all;
}

}  // namespace

std::size_t apply_spatial_split(const SpatialSplit& split, SortedRefs& refs, int order_axis,
                                const Scene& scene, SortedRefs& left_out, SortedRefs& right_out,
                                unsigned threads) {
  const int axis = split.axis;
  const float pos = split.position;
  Sides sides = classify_all(refs.axis[order_axis], axis, pos, scene, threads);
  format::Box3f left_box = sides.left_box, right_box = sides.right_box;
  const std::vector<const PrimRef*>& straddling = sides.straddling;
  const std::size_t left_whole = sides.left_whole, right_whole = sides.right_whole;
  // Straddlers in the parent's order, as they were decided before the arrays were kept sorted.
  std::vector<PrimRef> left, right;
  std::size_t left_count = left_whole + straddling.size();
  std::size_t right_count = right_whole + straddling.size();
  std::size_t added = 0;
  for (std::size_t k = 0; k < straddling.size(); ++k) {
    const PrimRef* r = straddling[k];
    const auto& [l, rr] = sides.clipped[k];
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
  // Unsplitting moved every reference to one side: no children (`refs` kept for the caller).
  if (left_whole + left.size() == 0 || right_whole + right.size() == 0) return added;
  parallel_for(3, threads, [&](std::size_t a) {
    children_on_axis(refs.axis[a], int(a), axis, pos, left, right, left_out.axis[a],
                     right_out.axis[a]);
  });
  return added;
}

}  // namespace kiln
