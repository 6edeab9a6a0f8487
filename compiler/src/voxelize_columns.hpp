// The surface voxelizer's inner loop: one triangle's voxels as runs along columns, decided by the
// separating-axis tests in closed form instead of voxel by voxel.
//
// Every one of the 13 axes of triangle_overlaps_box (Akenine-Moller 2001) is a slab test
// "c . X in [B_lo, B_hi]" on the voxel centre c, linear in c; these are also Schwarz & Seidel's
// (2010) plane and 2D edge-function tests. Along a column parallel to the axis `a` where the
// triangle's normal is largest, each test with a non-zero a-component bounds the centre's a
// coordinate to an interval, so a column's voxels are one run [lo, hi], computed with a few
// multiply-adds; tests with a zero a-component bound the columns (rows along v, then u). The box
// axes are the candidate range, which is exact.
//
// Exactness: the predicate evaluates each test in double with rounding, so it may differ from the
// exact-arithmetic test near the slab's boundary. Each test carries a margin `m` (see
// margin_of_* in voxelize_columns.cpp) that bounds the difference between the predicate's value
// and the exact value plus the error of our own evaluation; a voxel whose centre is farther than
// `m` inside every test is set, one farther than `m` outside some test is skipped, and the rest
// ("maybe") are decided by triangle_touches_voxel itself. So the output equals the predicate's
// voxel set exactly, and only voxels within ~1e-12 voxel of a boundary (or all voxels of a
// degenerate triangle) cost the full test. Corners must lie within 2^40 grid units of the
// origin (always so on a grid fitted to the scene); a triangle beyond that is skipped.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "kiln/compiler/voxelizer.hpp"

namespace kiln::voxelize_detail {

struct VoxelRange {
  std::int64_t lo[3], hi[3];  // inclusive; empty when lo > hi on an axis
};
inline bool is_empty(const VoxelRange& r) {
  return r.lo[0] > r.hi[0] || r.lo[1] > r.hi[1] || r.lo[2] > r.hi[2];
}

// Voxels whose closed box can meet the triangle's bounding box, clipped to `clip`: exactly the
// voxels that pass the predicate's three box-axis tests (the subtractions there are exact near
// the boundary, Sterbenz), so no margin is needed on these axes.
VoxelRange candidate_range(const GridTriangle& t, const VoxelRange& clip);

// One slab test as an interval of the local centre coordinate x along its level's axis:
// x in [lo + qu * cu + qv * cv, hi + qu * cu + qv * cv] (cu, cv: the local centre coordinates of
// the column's u and v), widened by its margin m (maybe). The sure interval is the maybe interval
// narrowed by twice the triangle's largest margin (lo_m + 2 max m >= lo + m for every test), so
// only the maybe bounds are evaluated.
struct SlabInterval {
  double lo_m, hi_m, qu, qv;
};

// floor and ceil of a double within +-2^52 without libm calls (the baseline, SSE2, has no
// rounding instruction, so std::floor is a call there).
inline std::int64_t floor_to_int(double x) {
  const auto i = std::int64_t(x);
  return i - std::int64_t(double(i) > x);
}
inline std::int64_t ceil_to_int(double x) {
  const auto i = std::int64_t(x);
  return i + std::int64_t(double(i) < x);
}

// Indices [lo, hi] (local: voxel index minus the triangle's origin) with centres j + 0.5 within
// [x_lo, x_hi], clipped to [clip_lo, clip_hi].
inline void centre_range(double x_lo, double x_hi, std::int64_t clip_lo, std::int64_t clip_hi,
                         std::int64_t& lo, std::int64_t& hi) {
  // Clamp first so the conversions never overflow (bounds may be huge or infinite).
  const double f_lo = std::clamp(x_lo - 0.5, double(clip_lo) - 1, double(clip_hi) + 1);
  const double f_hi = std::clamp(x_hi - 0.5, double(clip_lo) - 1, double(clip_hi) + 1);
  lo = std::max(clip_lo, ceil_to_int(f_lo));
  hi = std::min(clip_hi, floor_to_int(f_hi));
}

class TriangleColumns {
 public:
  /// Prepares the tests; false when the triangle touches no voxel at all.
  bool setup(const GridTriangle& t);
  /// The candidate range (every voxel the predicate can accept lies in it).
  const VoxelRange& range() const { return range_; }
  int dominant_axis() const { return a_; }
  /// The inclusive range of `a` indices (global) the triangle may reach over the columns
  /// [u0, u1] x [v0, v1] (global indices): the plane test's maybe-interval over the rectangle.
  void reach_along_a(std::int64_t u0, std::int64_t u1, std::int64_t v0, std::int64_t v1,
                     std::int64_t& a0, std::int64_t& a1) const;
  /// Reports every voxel of `clip` that triangle_touches_voxel accepts, once: runs of voxels
  /// along the dominant axis as run(c, a, a1) (c: the first voxel, global; the run goes to
  /// c[a] = a1), single voxels as voxel(x, y, z).
  template <class Run, class Voxel>
  void walk(const VoxelRange& clip, Run run, Voxel voxel);

 private:
  void add_test(const std::array<double, 3>& axis, double margin);
  void fill_v_table(std::int64_t v0, std::int64_t v1);
  void add_interval(double b_lo, double b_hi, double k, double q1, double q2, double margin,
                    int level);

  GridTriangle t_{};
  VoxelRange range_{};
  int a_ = 2, u_ = 0, v_ = 1;
  std::int64_t origin_[3] = {0, 0, 0};  // local origin (integers), per axis
  std::array<double, 3> p_[3]{};        // corners minus the origin
  double extent_ = 1;                   // M: bounds |corner - centre| over candidate voxels
  double sure_inset_ = 0;               // twice the largest margin of the tests
  bool uncertain_all_ = false;          // every voxel is decided by the exact predicate
  bool empty_ = false;                  // a test separates every voxel
  bool has_plane_ = false;              // the plane test bounds the a index (plane_)
  SlabInterval plane_{};
  // Tests per level: [0] bound the u index, [1] the v index per row, [2] the a index per column.
  // After setup, the a-index tests that depend on cu only move to [3] (once per row) and those
  // on cv only to [4] (once per v index, tabled): a column then evaluates only [2], mostly the
  // plane, since an edge axis cross(unit u, e) has no u component and cross(unit v, e) no v.
  SlabInterval tests_[5][10]{};
  int count_[5] = {0, 0, 0, 0, 0};
  std::vector<double> v_table_;  // per v index of the walk: lo_m, hi_m of [4]
};

// Narrows the maybe interval [lo, hi] by `tests` at (cu, cv).
inline void narrow(const SlabInterval* tests, int count, double cu, double cv, double& lo,
                   double& hi) {
  for (int k = 0; k < count; ++k) {
    const SlabInterval& s = tests[k];
    const double w = s.qu * cu + s.qv * cv;
    lo = std::max(lo, s.lo_m + w), hi = std::min(hi, s.hi_m + w);
  }
}

// The a-interval of the tests that depend on cv only, per local v index in [v0, v1].
inline void TriangleColumns::fill_v_table(std::int64_t v0, std::int64_t v1) {
  v_table_.resize(2 * std::size_t(v1 - v0 + 1));
  for (std::int64_t iv = v0; iv <= v1; ++iv) {
    double* t = &v_table_[2 * std::size_t(iv - v0)];
    t[0] = -INFINITY, t[1] = INFINITY;
    narrow(tests_[4], count_[4], 0, double(iv) + 0.5, t[0], t[1]);
  }
}

template <class Run, class Voxel>
void TriangleColumns::walk(const VoxelRange& clip, Run run, Voxel voxel) {
  VoxelRange r;
  for (int k = 0; k < 3; ++k)
    r.lo[k] = std::max(range_.lo[k], clip.lo[k]) - origin_[k],
    r.hi[k] = std::min(range_.hi[k], clip.hi[k]) - origin_[k];
  if (is_empty(r)) return;
  const int a = a_, u = u_, v = v_;
  const double inset = sure_inset_;
  double lo = -INFINITY, hi = INFINITY;
  std::int64_t u0, u1;
  narrow(tests_[0], count_[0], 0, 0, lo, hi);
  centre_range(lo, hi, r.lo[u], r.hi[u], u0, u1);
  const double u_sure_lo = lo + inset, u_sure_hi = hi - inset;
  fill_v_table(r.lo[v], r.hi[v]);
  std::int64_t c[3];
  auto exact = [&](std::int64_t from, std::int64_t to) {
    for (std::int64_t ia = from; ia <= to; ++ia) {
      c[a] = ia + origin_[a];
      const auto x = std::uint32_t(c[0]), y = std::uint32_t(c[1]), z = std::uint32_t(c[2]);
      if (triangle_touches_voxel(t_, x, y, z)) voxel(x, y, z);
    }
  };
  for (std::int64_t iu = u0; iu <= u1; ++iu) {
    const double cu = double(iu) + 0.5;
    const bool sure_u = !uncertain_all_ && cu >= u_sure_lo && cu <= u_sure_hi;
    std::int64_t v0, v1;
    lo = -INFINITY, hi = INFINITY;
    narrow(tests_[1], count_[1], cu, 0, lo, hi);
    centre_range(lo, hi, r.lo[v], r.hi[v], v0, v1);
    const double v_sure_lo = lo + inset, v_sure_hi = hi - inset;
    double row_lo = -INFINITY, row_hi = INFINITY;
    narrow(tests_[3], count_[3], cu, 0, row_lo, row_hi);
    c[u] = iu + origin_[u];
    for (std::int64_t iv = v0; iv <= v1; ++iv) {
      const double cv = double(iv) + 0.5;
      const double* t = &v_table_[2 * std::size_t(iv - r.lo[v])];
      lo = std::max(row_lo, t[0]), hi = std::min(row_hi, t[1]);
      narrow(tests_[2], count_[2], cu, cv, lo, hi);
      std::int64_t a0, a1, s0 = 1, s1 = 0;
      centre_range(lo, hi, r.lo[a], r.hi[a], a0, a1);
      if (a0 > a1) continue;
      c[v] = iv + origin_[v];
      if (sure_u && cv >= v_sure_lo && cv <= v_sure_hi)
        centre_range(lo + inset, hi - inset, r.lo[a], r.hi[a], s0, s1);
      if (s0 > s1) {
        exact(a0, a1);
        continue;
      }
      exact(a0, s0 - 1);  // within the margin of a bound: rare
      c[a] = s0 + origin_[a];
      run(c, a, s1 + origin_[a]);
      exact(s1 + 1, a1);
    }
  }
}

}  // namespace kiln::voxelize_detail
