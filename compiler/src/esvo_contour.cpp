#include "esvo_contour.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "kiln/formats/voxel_grid.hpp"

namespace kiln::esvo {

namespace {

// A candidate's vertices may sit exactly on a quantisation step; the runtime evaluates slabs in
// float, so every slab keeps a tenth of a step of room on both sides.
constexpr double kQuantMargin = 0.1;
// A contour must cut away at least 1/16 of the cube's extent along its normal to be worth 4 bytes.
constexpr int kMaxThickness = 120;
constexpr int kScoreCells = 8;  // sub-cells per axis when scoring candidates
constexpr int kMaxCandidates = 7;

int dominant_axis(const double n[3]) {
  int a = 0;
  for (int i = 1; i < 3; ++i)
    if (std::fabs(n[i]) > std::fabs(n[a])) a = i;
  return a;
}

// The cells k in [0, count) along axis a (cell k spans oa + [k, k+1] * h) whose closed boxes,
// within the column [b0, b1] x [c0, c1] on the other two axes, meet the slab. Rounding widens.
bool column_range(const Slab& s, int a, double b0, double b1, double c0, double c1, double oa,
                  double h, int count, int& k0, int& k1) {
  const int b = (a + 1) % 3, c = (a + 2) % 3;
  const double nb = s.n[b], nc = s.n[c], na = s.n[a];
  const double cmin = std::min(nb * b0, nb * b1) + std::min(nc * c0, nc * c1);
  const double cmax = std::max(nb * b0, nb * b1) + std::max(nc * c0, nc * c1);
  if (na == 0) {
    if (cmin > s.hi || cmax < s.lo) return false;
    k0 = 0, k1 = count - 1;
    return true;
  }
  const double lo = s.lo - na * oa, hi = s.hi - na * oa, step = na * h;
  double first, last;
  if (na > 0)
    first = (lo - cmax) / step - 1, last = (hi - cmin) / step;
  else
    first = (hi - cmin) / step - 1, last = (lo - cmax) / step;
  constexpr double kSlack = 1e-9;
  first = std::ceil(first - kSlack), last = std::floor(last + kSlack);
  k0 = int(std::max(first, 0.0));
  k1 = int(std::min(last, double(count - 1)));
  return first <= double(count - 1) && last >= 0 && k0 <= k1;
}

// Sub-cells of the cube's 8^3 grid meeting both slabs: the over-estimate a candidate leaves.
int cells_kept(const Slab& slab, const Slab* parent, const Cube& cube) {
  const int a = dominant_axis(slab.n), b = (a + 1) % 3, c = (a + 2) % 3;
  const double h = double(cube.side) / kScoreCells;
  int kept = 0;
  for (int ib = 0; ib < kScoreCells; ++ib)
    for (int ic = 0; ic < kScoreCells; ++ic) {
      const double b0 = cube.corner[b] + ib * h, c0 = cube.corner[c] + ic * h;
      int k0, k1;
      if (!column_range(slab, a, b0, b0 + h, c0, c0 + h, cube.corner[a], h, kScoreCells, k0, k1))
        continue;
      int p0, p1;
      if (parent != nullptr) {
        if (!column_range(*parent, a, b0, b0 + h, c0, c0 + h, cube.corner[a], h, kScoreCells, p0,
                          p1))
          continue;
        k0 = std::max(k0, p0), k1 = std::min(k1, p1);
      }
      kept += std::max(0, k1 - k0 + 1);
    }
  return kept;
}

struct Candidate {
  double d[3];
};

void area_vector(const ClipPolygon& p, double out[3]) {
  out[0] = out[1] = out[2] = 0;
  for (int i = 1; i + 1 < p.n; ++i) {
    double e1[3], e2[3];
    for (int k = 0; k < 3; ++k)
      e1[k] = p.v[i].c[k] - p.v[0].c[k], e2[k] = p.v[i + 1].c[k] - p.v[0].c[k];
    out[0] += 0.5 * (e1[1] * e2[2] - e1[2] * e2[1]);
    out[1] += 0.5 * (e1[2] * e2[0] - e1[0] * e2[2]);
    out[2] += 0.5 * (e1[0] * e2[1] - e1[1] * e2[0]);
  }
}

double length(const double v[3]) {
  return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

// The tightest quantised slab along the quantised direction `d` holding every vertex.
std::optional<format::Contour> quantise(const Candidate& cand,
                                        std::span<const ClipPolygon> polygons, const Cube& cube) {
  const double m = std::max({std::fabs(cand.d[0]), std::fabs(cand.d[1]), std::fabs(cand.d[2])});
  if (!(m > 0)) return std::nullopt;
  format::Contour c{};
  for (int k = 0; k < 3; ++k) c.normal[k] = int(std::lround(cand.d[k] * 31.0 / m));
  const double unit = format::contour_extent(c) / 128.0;
  const double s = cube.side;
  double dmin = INFINITY, dmax = -INFINITY;
  for (const ClipPolygon& p : polygons)
    for (int i = 0; i < p.n; ++i) {
      double d = 0;
      for (int k = 0; k < 3; ++k) d += c.normal[k] * ((p.v[i].c[k] - cube.corner[k]) / s - 0.5);
      dmin = std::min(dmin, d), dmax = std::max(dmax, d);
    }
  const double lo = std::max(std::floor(dmin / unit - kQuantMargin), -64.0);
  const double hi = std::min(std::ceil(dmax / unit + kQuantMargin), 64.0);
  c.position = int(std::min(lo, 63.0));
  c.thickness = int(hi) - c.position;
  if (c.thickness < 0 || c.thickness > kMaxThickness) return std::nullopt;
  return c;
}

}  // namespace

Slab slab_of(const format::Contour& contour, const Cube& cube) {
  const double unit = format::contour_extent(contour) / 128.0;
  const double s = cube.side;
  Slab slab;
  double centre = 0;
  for (int k = 0; k < 3; ++k) {
    slab.n[k] = contour.normal[k];
    centre += contour.normal[k] * (cube.corner[k] + 0.5 * s);
  }
  slab.lo = s * contour.position * unit + centre;
  slab.hi = s * (contour.position + contour.thickness) * unit + centre;
  return slab;
}

std::optional<FittedContour> fit_contour(std::span<const ClipPolygon> polygons, const Cube& cube,
                                         const Slab* parent) {
  if (polygons.empty()) return std::nullopt;
  // Candidates: the mean normal, then the largest pieces' normals, skipping near-duplicates.
  std::vector<std::pair<double, Candidate>> pieces;
  Candidate mean{{0, 0, 0}};
  for (const ClipPolygon& p : polygons) {
    Candidate area;
    area_vector(p, area.d);
    for (int k = 0; k < 3; ++k) mean.d[k] += area.d[k];
    const double l = length(area.d);
    if (l > 0) pieces.push_back({l, area});
  }
  std::stable_sort(pieces.begin(), pieces.end(),
                   [](const auto& x, const auto& y) { return x.first > y.first; });
  std::vector<Candidate> candidates;
  auto add = [&](const Candidate& c) {
    const double l = length(c.d);
    if (!(l > 0)) return;
    const Candidate unit{{c.d[0] / l, c.d[1] / l, c.d[2] / l}};
    for (const Candidate& other : candidates)
      if (std::fabs(unit.d[0] * other.d[0] + unit.d[1] * other.d[1] + unit.d[2] * other.d[2]) >
          0.9995)
        return;
    candidates.push_back(unit);
  };
  add(mean);
  for (const auto& [area, piece] : pieces) {
    if (int(candidates.size()) >= kMaxCandidates) break;
    add(piece);
  }
  std::optional<FittedContour> best;
  int best_kept = 0, best_thickness = 0;
  for (const Candidate& cand : candidates) {
    const auto contour = quantise(cand, polygons, cube);
    if (!contour) continue;
    const Slab slab = slab_of(*contour, cube);
    const int kept = cells_kept(slab, parent, cube);
    if (!best || kept < best_kept || (kept == best_kept && contour->thickness < best_thickness)) {
      best = FittedContour{format::encode_contour(*contour), slab};
      best_kept = kept, best_thickness = contour->thickness;
    }
  }
  return best;
}

bool slab_covered(const Slab& slab, const Slab* parent, const Cube& cube,
                  std::span<const std::uint64_t> surface, std::uint64_t code_base,
                  std::uint32_t reach) {
  const std::uint32_t s = cube.side;
  if (s > kMaxCoveredSide || s < 2) return false;
  const int a = dominant_axis(slab.n), b = (a + 1) % 3, c = (a + 2) % 3;
  // One bit per cell along `a`, per column: the surface, then dilated by `reach` along `a`.
  std::vector<std::uint64_t> columns(std::size_t(s) * s);
  for (const std::uint64_t code : surface) {
    const std::uint64_t rel = code - code_base;
    const std::uint32_t p[3] = {format::compact_bits(rel), format::compact_bits(rel >> 1),
                                format::compact_bits(rel >> 2)};
    columns[std::size_t(p[b]) * s + p[c]] |= std::uint64_t(1) << p[a];
  }
  for (std::uint32_t ib = 0; ib < s; ++ib)
    for (std::uint32_t ic = 0; ic < s; ++ic) {
      const double b0 = double(cube.corner[b]) + ib, c0 = double(cube.corner[c]) + ic;
      int k0, k1;
      if (!column_range(slab, a, b0, b0 + 1, c0, c0 + 1, cube.corner[a], 1, int(s), k0, k1))
        continue;
      if (parent != nullptr) {
        int p0, p1;
        if (!column_range(*parent, a, b0, b0 + 1, c0, c0 + 1, cube.corner[a], 1, int(s), p0, p1))
          continue;
        k0 = std::max(k0, p0), k1 = std::min(k1, p1);
        if (k0 > k1) continue;
      }
      const std::uint64_t bits = columns[std::size_t(ib) * s + ic];
      std::uint64_t near = bits;
      for (std::uint32_t r = 1; r <= reach && r < 64; ++r) near |= bits << r | bits >> r;
      const std::uint64_t wanted =
          (k1 - k0 + 1 >= 64 ? ~std::uint64_t(0) : ((std::uint64_t(1) << (k1 - k0 + 1)) - 1)) << k0;
      if ((wanted & ~near) != 0) return false;
    }
  return true;
}

}  // namespace kiln::esvo
