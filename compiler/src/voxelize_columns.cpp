// Setup of the closed-form column tests (voxelize_columns.hpp) and their error margins.
//
// Why the margins hold. Let u = 2^-53 (unit roundoff) and M = the largest extent of the
// triangle's bounding box plus 2 (grid units), so that for every candidate voxel with centre c:
// |corner - c| <= M per axis, |edge| <= 2M per axis, and the local centre (c minus our integer
// origin) is within M as well. The predicate (triangle_overlaps_box) computes a = fl(v - c)
// (error <= uM per component), edges e = fl(b - a) (<= 4uM), and for each axis X a slab test.
//  - Edge axes X = cross(unit, e) take two components of e exactly, so |X - X_exact| <= 4uM
//    per component and |X| <= 2M; p = a . X then differs from the exact A . X_exact by at most
//    uM*4M + M*8uM + 12uM^2 (the two products and one sum rounded) = 24uM^2, and r by 8uM:
//    the separating quantity by <= 32uM^2.
//  - The normal n = cross(e0, e1): |n - N| <= 48uM^2 per component, |N| <= 8M^2; p = a . n
//    differs by <= 3(uM*8M^2 + M*48uM^2) + 72uM^3 = 240uM^3, r by 96uM^2: <= 336uM^3.
// Our own evaluation (corners minus an integer origin, edges, axes, slab bounds, c . X) has the
// same structure and the same bounds (<= 32uM^2 + 12uM^2 and <= 336uM^3 + 144uM^3). The margins
// below, 256uM^2 and 2048uM^3, exceed the sum of both by more than 2x (the O(u^2) terms are far
// below that). Dividing by the axis' component along the level's axis turns them into a distance
// along it; the division and the multiply-adds that evaluate the bound per column add at most
// 4u(|bound| + (|qu| + |qv|)M + 1), covered by the 16u(...) term. Underflow only adds absolute
// errors far below u (M >= 2). In grid units the margin is ~1e-12 voxel for ordinary triangles;
// it grows only for slivers and degenerate triangles, whose voxels then go to the exact test.
#include "voxelize_columns.hpp"

#include <limits>

namespace kiln::voxelize_detail {

namespace {

constexpr double kRoundoff = 0x1p-53;

double component(const std::array<double, 3>& v, int i) {
  return v[std::size_t(i)];
}

// cross(unit axis i, e), component by component as the predicate forms it.
std::array<double, 3> cross_unit(int i, const std::array<double, 3>& e) {
  if (i == 0) return {0, -e[2], e[1]};
  if (i == 1) return {e[2], 0, -e[0]};
  return {-e[1], e[0], 0};
}

}  // namespace

VoxelRange candidate_range(const GridTriangle& t, const VoxelRange& clip) {
  VoxelRange r;
  for (int a = 0; a < 3; ++a) {
    const double lo =
        std::min({format::at(t.v[0], a), format::at(t.v[1], a), format::at(t.v[2], a)});
    const double hi =
        std::max({format::at(t.v[0], a), format::at(t.v[1], a), format::at(t.v[2], a)});
    // A box [k, k+1] touches a coordinate in [lo, hi] for k in [ceil(lo) - 1, floor(hi)].
    r.lo[a] = std::max(clip.lo[a], ceil_to_int(lo) - 1);
    r.hi[a] = std::min(clip.hi[a], floor_to_int(hi));
  }
  return r;
}

bool TriangleColumns::setup(const GridTriangle& t) {
  t_ = t;
  for (int k = 0; k < 3; ++k) {
    const double v[3] = {format::at(t.v[0], k), format::at(t.v[1], k), format::at(t.v[2], k)};
    for (const double x : v)
      if (!std::isfinite(x) || std::fabs(x) > 0x1p40) return false;  // outside any grid
  }
  VoxelRange everything;
  for (int k = 0; k < 3; ++k)
    everything.lo[k] = -(std::int64_t{1} << 50), everything.hi[k] = -everything.lo[k];
  range_ = candidate_range(t, everything);
  if (is_empty(range_)) return false;
  double extent = 0;
  for (int k = 0; k < 3; ++k) {
    origin_[k] = floor_to_int(
        std::min({format::at(t.v[0], k), format::at(t.v[1], k), format::at(t.v[2], k)}));
    const double lo = double(origin_[k]);
    for (int j = 0; j < 3; ++j) {
      p_[j][std::size_t(k)] = format::at(t.v[j], k) - lo;
      extent = std::max(extent, p_[j][std::size_t(k)]);
    }
  }
  extent_ = extent + 2;
  std::array<double, 3> e[3];
  for (int j = 0; j < 3; ++j)
    for (std::size_t k = 0; k < 3; ++k) e[j][k] = p_[(j + 1) % 3][k] - p_[j][k];
  const std::array<double, 3> n = {e[0][1] * e[1][2] - e[0][2] * e[1][1],
                                   e[0][2] * e[1][0] - e[0][0] * e[1][2],
                                   e[0][0] * e[1][1] - e[0][1] * e[1][0]};
  a_ = 0;
  for (int k = 1; k < 3; ++k)
    if (std::fabs(component(n, k)) > std::fabs(component(n, a_))) a_ = k;
  if (n[0] == 0 && n[1] == 0 && n[2] == 0)  // degenerate: walk along the longest extent
    for (int k = 0; k < 3; ++k)
      if (range_.hi[k] - range_.lo[k] > range_.hi[a_] - range_.lo[a_]) a_ = k;
  u_ = (a_ + 1) % 3, v_ = (a_ + 2) % 3;
  std::fill(std::begin(count_), std::end(count_), 0);
  sure_inset_ = 0;
  uncertain_all_ = empty_ = false;
  const double m = extent_;
  add_test(n, 2048 * kRoundoff * m * m * m);
  has_plane_ = count_[2] == 1;
  if (has_plane_) plane_ = tests_[2][0];
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) {
      // An edge parallel to axis i gives the exact zero axis, which never separates.
      const int p = (i + 1) % 3, q = (i + 2) % 3;
      if (format::at(t.v[(j + 1) % 3], p) == format::at(t.v[j], p) &&
          format::at(t.v[(j + 1) % 3], q) == format::at(t.v[j], q))
        continue;
      add_test(cross_unit(i, e[j]), 256 * kRoundoff * m * m);
    }
  // Split the column tests by what they depend on (see tests_).
  int general = 0;
  for (int k = 0; k < count_[2]; ++k) {
    const SlabInterval& s = tests_[2][k];
    const int level = s.qv == 0 ? 3 : s.qu == 0 ? 4 : 2;
    if (level == 2)
      tests_[2][general++] = s;
    else
      tests_[level][count_[level]++] = s;
  }
  count_[2] = general;
  return !empty_;
}

// The test "c . axis in [min_j p_j . axis - r, max_j p_j . axis + r]", filed at the finest level
// whose axis component is non-zero (a: per column, v: per row, u: per triangle).
void TriangleColumns::add_test(const std::array<double, 3>& axis, double margin) {
  double lo = INFINITY, hi = -INFINITY;
  for (int j = 0; j < 3; ++j) {
    const double p = p_[j][0] * axis[0] + p_[j][1] * axis[1] + p_[j][2] * axis[2];
    lo = std::min(lo, p), hi = std::max(hi, p);
  }
  const double r = 0.5 * (std::fabs(axis[0]) + std::fabs(axis[1]) + std::fabs(axis[2]));
  lo -= r, hi += r;
  const double ka = component(axis, a_), ku = component(axis, u_), kv = component(axis, v_);
  if (ka != 0)
    add_interval(lo, hi, ka, ku, kv, margin, 2);
  else if (kv != 0)
    add_interval(lo, hi, kv, ku, 0, margin, 1);
  else if (ku != 0)
    add_interval(lo, hi, ku, 0, 0, margin, 0);
  else if (0 < lo - margin || 0 > hi + margin)
    empty_ = true;  // separates every voxel
  else if (!(lo + margin <= 0 && 0 <= hi - margin))
    uncertain_all_ = true;
}

void TriangleColumns::add_interval(double b_lo, double b_hi, double k, double q1, double q2,
                                   double margin, int level) {
  // A reciprocal instead of four divisions: one more rounding each, within the 16u term.
  const double inv = 1 / k;
  const double lo = (k > 0 ? b_lo : b_hi) * inv, hi = (k > 0 ? b_hi : b_lo) * inv;
  const double qu = -q1 * inv, qv = -q2 * inv;
  const double m = margin * std::fabs(inv) + 16 * kRoundoff *
                                                 (std::max(std::fabs(lo), std::fabs(hi)) +
                                                  (std::fabs(qu) + std::fabs(qv)) * extent_ + 1);
  // NaN or infinity anywhere makes the sum non-finite (lo, hi, |qu|, |qv| <= m / (16u)).
  if (!(std::fabs(m) < INFINITY)) {
    uncertain_all_ = true;  // no usable bound: the exact test decides every voxel
    return;
  }
  tests_[level][count_[level]++] = {lo - m, hi + m, qu, qv};
  sure_inset_ = std::max(sure_inset_, 2 * m);
}

void TriangleColumns::reach_along_a(std::int64_t u0, std::int64_t u1, std::int64_t v0,
                                    std::int64_t v1, std::int64_t& a0, std::int64_t& a1) const {
  a0 = range_.lo[a_], a1 = range_.hi[a_];
  if (!has_plane_) return;
  const SlabInterval& s = plane_;
  double lo = INFINITY, hi = -INFINITY;
  for (const std::int64_t iu : {u0, u1})
    for (const std::int64_t iv : {v0, v1}) {
      const double w =
          s.qu * (double(iu - origin_[u_]) + 0.5) + s.qv * (double(iv - origin_[v_]) + 0.5);
      lo = std::min(lo, s.lo_m + w), hi = std::max(hi, s.hi_m + w);
    }
  std::int64_t l, h;
  centre_range(lo, hi, range_.lo[a_] - origin_[a_], range_.hi[a_] - origin_[a_], l, h);
  // One voxel of slack: the columns' own evaluation rounds differently from the corners'.
  a0 = std::max(range_.lo[a_], l + origin_[a_] - 1);
  a1 = std::min(range_.hi[a_], h + origin_[a_] + 1);
}

}  // namespace kiln::voxelize_detail
