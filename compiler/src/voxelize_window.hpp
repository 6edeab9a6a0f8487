// The voxelizer's brute-force window kernel for small triangles: every voxel of a triangle's
// candidate range (at most kWindowsPerAxis * kWindowSide = 12 voxels on every axis) against the
// ten non-box slab tests of triangle_overlaps_box at once, in SIMD registers, with no filing of
// the tests by their zero components and no divisions (the column walk, voxelize_columns.hpp,
// does both; it stays the path for larger triangles and for CPUs without AVX2). Kernels: AVX-512
// and AVX2 (voxelize_window_avx512.cpp, _avx2.cpp), chosen at run time (voxelize_kernel.cpp:
// __builtin_cpu_supports, KILN_VOXEL_KERNEL, set_voxel_kernel); every kernel gives the voxel set
// of triangle_touches_voxel exactly, as argued below.
//
// Windows and lanes. The range is covered by 4x4x4 windows, 1 to 3 per axis, the first starting
// at the range's first voxel g (global) and the next ones 4 voxels further along each axis. Lane L
// (0..63) of a window holds the voxel whose global coordinate along axis a is congruent to
// coord_a(L) = bit a of L | bit (3 + a) of L << 1 modulo 4, i.e. the window's voxel (start_a +
// ((coord_a(L) - s_a) & 3)) with s_a = g_a & 3 (the same for every window). So a lane's index is
// its voxel's Morton index within its 4x4x4 leaf, and the leaf along a is the window start's
// (coord_a >= s_a) or the next one: a window's mask splits into its (up to 8) leaves by ANDs with
// constant masks (kWindowLaneMasks), with no bit shuffling.
//
// Tests. The plane test "c . n in [min_j p_j . n - r, max_j p_j . n + r]" (c: the local voxel
// centre, p_j: the corners minus the integer origin) depends on all three coordinates and is
// evaluated on the 64 lanes; an edge test on the axis cross(unit_i, e_j) has a zero i component,
// so it is evaluated on the 16 (p, q) = (i + 1, i + 2) pairs (2D lane l: p0 | q0 << 1 | p1 << 2 |
// q1 << 3) and its mask expanded along i by a table (kWindowExpand). The axes, projections and
// radii are formed in double with add_test / add_edge_test's arithmetic (the AVX-512 setup
// projects corners j and j + 2 only on edge j's axes: corner j + 1's exact projection equals
// corner j's, so the min and max carry the same error bound), and each test carries the same
// margin m (2048uM^3 for the plane, 256uM^2 for edges; u = 2^-53, M = extent + 2). The kernels
// then evaluate c . X in single precision, so each test's margin grows by a bound e_f of that
// evaluation's error (window_float_bounds): maybe interval [lo - r - m', hi + r + m'], sure
// interval [lo - r + m', hi + r - m'] with m' >= m + e_f. A voxel is set when its centre is in
// every sure interval, decided by triangle_touches_voxel when it is in every maybe interval only,
// skipped otherwise.
//
// Why the double margins hold (notation of voxelize_columns.cpp: the predicate's value of a
// test's separating quantity differs from the exact one by <= 32uM^2 (edges) and <= 336uM^3
// (plane)). Our double values, no FMA: corners minus the integer origin err by <= uM per
// component, edges by <= 4uM, an edge axis (two edge components) by <= 4uM per component, the
// normal by <= 48uM^2 (|N| <= 8M^2). Projections p . X: <= 20uM^2 (edges; two products and a
// sum) and <= 240uM^3 (plane); r: <= 4uM^2 and <= 55uM^3. The centre c is exact (a half-integer,
// |c| <= M over the candidate range; lanes outside it are masked off), and c . X with our X
// differs from c . X_exact by |c| |X - X_exact| <= 8uM^2 and <= 144uM^3. The bounds
// fl(fl(lo - r) -+ m') round twice: <= 10uM^2 (|lo|, |hi| <= 4M^2, r <= 2M) and <= 60uM^3 (|lo| <=
// 24M^3, r <= 12M^2). Our total: <= 42uM^2 and <= 499uM^3; with the predicate's, <= 74uM^2 <
// 256uM^2 and <= 835uM^3 < 2048uM^3.
//
// Why the float evaluation holds. Each kernel rounds X to float (relative error <= 2^-24 per
// component), takes the centre exactly (a half-integer below 2^23) and forms c . X with rounded
// products and sums: ((n0 c0 + n1 c1) + n2 c2) for the plane, (xp cp + xq cq) for an edge; the
// result differs from c . X (our X, exact arithmetic) by <= 5 * 2^-24 * sum_k |X_k| |c_k| <=
// 5 * 2^-24 * M * 2r (r = sum_k |X_k| / 2), so e_f = 12 * 2^-24 * M * r bounds it. The bounds,
// computed in double as lo - r -+ m' and hi + r -+ m' with m' = e + 2^-22 (max(|lo - r|,
// |hi + r|) + e), e = m + e_f, are then rounded to float, which moves them by <= 2^-24
// (|bound|) <= m' - e: the float maybe bounds still contain [lo - r - e, hi + r + e] and the
// float sure bounds lie within [lo - r + e, hi + r - e]. So a lane in every float sure interval
// has its exact centre value inside each slab by more than m (the predicate accepts it), and a
// lane outside some float maybe interval has it outside by more than m (the predicate rejects
// it). A test the predicate skips (edge parallel to axis i) gets the slab [-1e30, 1e30], which
// every lane passes, maybe and sure. A degenerate triangle (n = 0) has the plane test "0 in
// [-m', m']": every centre is maybe and none is sure, so the predicate decides every voxel, as in
// the column walk. Windows have M <= 15 and |c . X| <= 1e5, so nothing overflows or underflows.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

#include "kiln/compiler/voxelizer.hpp"

namespace kiln::voxelize_detail {

constexpr int kWindowSide = 4;      // a window's side
constexpr int kWindowsPerAxis = 3;  // at most 3 windows per axis: candidate ranges up to 12
constexpr int kWindowsMax = kWindowsPerAxis * kWindowsPerAxis * kWindowsPerAxis;

/// What a window kernel needs: the triangle (for the edge-parallel rule), its corners minus the
/// integer origin, M, the local centre of the window's first voxel per axis and s_a = g_a & 3.
struct WindowJob {
  const GridTriangle* t;
  const std::array<double, 3>* p;  // three corners, local
  double extent;
  double base[3];
  unsigned s[3];
  unsigned windows[3];  // 4x4x4 windows along each axis (1..kWindowsPerAxis), from the range's
                        // first voxel
};

/// The window's lanes (see above) in every maybe interval and in every sure interval.
struct WindowMasks {
  std::uint64_t maybe, sure;
};

/// The ten slab tests as the kernels evaluate them: the plane test, then the edge tests by axis i
/// (entry 3 i + j: edge j's axis cross(unit_i, e_j), components xp, xq along i + 1, i + 2).
struct WindowTests {
  double n[3], xp[9], xq[9];
  // The slabs without margins ([lo - r, hi + r]; +-1e30 for skipped edges), r and the margins,
  // for the float kernel's bounds (window_float_bounds).
  double plane_slab[2], plane_r, plane_m;
  double slab_lo[9], slab_hi[9], r[9], edge_m;
};

/// Writes the masks of window (kx, ky, kz) (its first voxel 4 k_a after the range's first voxel
/// along each axis a) to out[kx + kWindowsPerAxis (ky + kWindowsPerAxis kz)].
using WindowKernel = void (*)(const WindowJob&, WindowMasks* out);

/// The kernels (nullptr when not compiled for this target); a caller checks the CPU first.
WindowKernel window_kernel_avx2();
WindowKernel window_kernel_avx512();
/// The kernel voxel_kernel() selects (nullptr: the column walk for every triangle).
WindowKernel selected_window_kernel();

constexpr int window_coord(int lane, int a) {
  return (lane >> a & 1) | (lane >> (3 + a) & 1) << 1;
}

// Per axis a and s_a: lanes with coord_a >= s_a (in the first leaf along a), and lanes whose
// offset (coord_a - s_a) & 3 lies in [lo, hi] (kBox[a][s][lo][hi]; empty when lo > hi).
struct WindowLaneMasks {
  std::uint64_t first_leaf[3][4];
  std::uint64_t box[3][4][4][4];
};
constexpr WindowLaneMasks make_window_lane_masks() {
  WindowLaneMasks t{};
  for (int a = 0; a < 3; ++a)
    for (int s = 0; s < 4; ++s)
      for (int lane = 0; lane < 64; ++lane) {
        const int c = window_coord(lane, a), offset = (c - s) & 3;
        if (c >= s) t.first_leaf[a][s] |= std::uint64_t{1} << lane;
        for (int lo = 0; lo < 4; ++lo)
          for (int hi = lo; hi < 4; ++hi)
            if (offset >= lo && offset <= hi) t.box[a][s][lo][hi] |= std::uint64_t{1} << lane;
      }
  return t;
}
inline constexpr WindowLaneMasks kWindowLaneMasks = make_window_lane_masks();

// A 2D mask of the plane (i + 1, i + 2) as 3D lanes (every coord_i): the low byte (q1 = 0)
// through the table, the high byte through the table shifted to q1 = 1 (Morton bit 3 + q).
struct WindowExpand {
  std::uint64_t bits[3][256];
};
constexpr WindowExpand make_window_expand() {
  WindowExpand t{};
  for (int i = 0; i < 3; ++i) {
    const int p = (i + 1) % 3, q = (i + 2) % 3;
    for (int byte = 0; byte < 256; ++byte)
      for (int l = 0; l < 8; ++l) {
        if ((byte >> l & 1) == 0) continue;
        const int cp = (l & 1) | (l >> 2 & 1) << 1, cq = l >> 1 & 1;
        for (int ci = 0; ci < 4; ++ci) {
          const int lane =
              (cp & 1) << p | (cp >> 1) << (3 + p) | cq << q | (ci & 1) << i | (ci >> 1) << (3 + i);
          t.bits[i][byte] |= std::uint64_t{1} << lane;
        }
      }
  }
  return t;
}
inline constexpr WindowExpand kWindowExpand = make_window_expand();

[[gnu::always_inline]] inline std::uint64_t expand_window_mask(int i, unsigned mask16) {
  const int q = (i + 2) % 3;
  return kWindowExpand.bits[i][mask16 & 255] | kWindowExpand.bits[i][mask16 >> 8] << (8 << q);
}

// The edges e_j = p_(j+1) - p_j (e[j][axis]) and the plane test: the normal n (setup's
// arithmetic), the slab [min_j p_j . n - r, max_j p_j . n + r], r and the margin 2048uM^3.
struct WindowPlane {
  double e[3][3], n[3], slab[2], r, m;
};
[[gnu::always_inline]] inline void window_plane(const WindowJob& job, WindowPlane& w) {
  const std::array<double, 3>* p = job.p;
  for (int j = 0; j < 3; ++j)
    for (int k = 0; k < 3; ++k) w.e[j][k] = p[(j + 1) % 3][k] - p[j][k];
  const double(&e)[3][3] = w.e;
  w.n[0] = e[0][1] * e[1][2] - e[0][2] * e[1][1];
  w.n[1] = e[0][2] * e[1][0] - e[0][0] * e[1][2];
  w.n[2] = e[0][0] * e[1][1] - e[0][1] * e[1][0];
  double lo = INFINITY, hi = -INFINITY;
  for (int j = 0; j < 3; ++j) {
    const double d = p[j][0] * w.n[0] + p[j][1] * w.n[1] + p[j][2] * w.n[2];
    lo = std::min(lo, d), hi = std::max(hi, d);
  }
  w.r = 0.5 * (std::fabs(w.n[0]) + std::fabs(w.n[1]) + std::fabs(w.n[2]));
  w.slab[0] = lo - w.r, w.slab[1] = hi + w.r;
  w.m = 2048 * 0x1p-53 * job.extent * job.extent * job.extent;
}

// The ten tests of the job's triangle (add_test / add_edge_test's arithmetic; see above). A
// skipped edge test gets the slab [-1e30, 1e30] (passes every centre; finite, so that margins
// added to it stay finite).
[[gnu::always_inline]] inline void window_tests(const WindowJob& job, WindowTests& w) {
  WindowPlane plane;
  window_plane(job, plane);
  const std::array<double, 3>* p = job.p;
  const double(&e)[3][3] = plane.e;
  const double m_edge = 256 * 0x1p-53 * job.extent * job.extent;
  for (int k = 0; k < 3; ++k) w.n[k] = plane.n[k];
  w.plane_slab[0] = plane.slab[0], w.plane_slab[1] = plane.slab[1];
  w.plane_r = plane.r, w.plane_m = plane.m, w.edge_m = m_edge;
  for (int i = 0; i < 3; ++i) {
    const int a = (i + 1) % 3, b = (i + 2) % 3;
    for (int j = 0; j < 3; ++j) {
      const int t = 3 * i + j;
      const double xp = -e[j][b], xq = e[j][a];
      double lo = INFINITY, hi = -INFINITY, r = 0.5 * (std::fabs(xp) + std::fabs(xq));
      if (xp == 0 && xq == 0 &&
          format::at(job.t->v[(j + 1) % 3], a) == format::at(job.t->v[j], a) &&
          format::at(job.t->v[(j + 1) % 3], b) == format::at(job.t->v[j], b)) {
        lo = -1e30, hi = 1e30;  // the predicate skips it: passes every centre
      } else {
        for (int k = 0; k < 3; ++k) {
          const double d = p[k][a] * xp + p[k][b] * xq;
          lo = std::min(lo, d), hi = std::max(hi, d);
        }
        lo -= r, hi += r;
      }
      w.xp[t] = xp, w.xq[t] = xq;
      w.slab_lo[t] = lo, w.slab_hi[t] = hi, w.r[t] = r;
    }
  }
}

// A test's maybe and sure bounds for the float kernel (see the header comment): the slab
// [lo, hi] with margin m widened by the float evaluation's error 12 * 2^-24 * M * r (r: half the
// sum of |X| components) and by the bounds' own rounding to float.
[[gnu::always_inline]] inline void window_float_bounds(double lo, double hi, double m, double r,
                                                       double extent, float* out) {
  const double e = m + 12 * 0x1p-24 * extent * r;
  const double mf = e + 0x1p-22 * (std::max(std::fabs(lo), std::fabs(hi)) + e);
  out[0] = float(lo - mf), out[1] = float(hi + mf), out[2] = float(lo + mf),
  out[3] = float(hi - mf);
}

}  // namespace kiln::voxelize_detail
