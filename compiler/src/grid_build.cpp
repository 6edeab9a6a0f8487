// The uniform grid builder and the pieces both grid builders share: the density rule, the padded
// box, and the compressed-row cell lists built by a count pass, prefix sums and a fill pass over
// the triangles, then a counting sort by cell (Kalojanov & Slusallek's sort-based construction
// in its sequential-scatter form), so the bytes never depend on the thread count.
#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include "kiln/compiler/grid_builder.hpp"
#include "kiln/runtime/parallel.hpp"
#include "kiln/runtime/triangle_geometry.hpp"

namespace kiln {

namespace {

// Per axis: how far a cell's box is padded for the overlap test, so that rounding in the
// traversal's cell choice (a neighbour cell at a boundary or corner) never loses a triangle.
std::array<double, 3> cell_padding(const GridFrame& f) {
  std::array<double, 3> pad{};
  for (int a = 0; a < 3; ++a) {
    const double cell = (double(f.hi[a]) - double(f.lo[a])) / f.res[a];
    const double magnitude = std::max(std::fabs(double(f.lo[a])), std::fabs(double(f.hi[a])));
    pad[a] = cell * 1e-3 + magnitude * 0x1p-20;
  }
  return pad;
}

// Calls fn(linear cell) for every cell of `f` whose padded box triangle t meets.
template <class Fn>
void overlapped_cells(const GridFrame& f, const std::array<double, 3>& pad,
                      const format::RayTriangle& t, Fn&& fn) {
  const format::Double3 v[3] = {to_d(t.v0), to_d(t.v1), to_d(t.v2)};
  std::uint32_t first[3], last[3];
  for (int a = 0; a < 3; ++a) {
    const double lo = std::min({at(v[0], a), at(v[1], a), at(v[2], a)});
    const double hi = std::max({at(v[0], a), at(v[1], a), at(v[2], a)});
    if (!cell_range(f, a, lo, hi, first[a], last[a])) return;
  }
  std::uint32_t c[3];
  for (c[2] = first[2]; c[2] <= last[2]; ++c[2])
    for (c[1] = first[1]; c[1] <= last[1]; ++c[1])
      for (c[0] = first[0]; c[0] <= last[0]; ++c[0]) {
        format::Double3 lo, hi;
        for (int a = 0; a < 3; ++a) {
          at(lo, a) = double(f.plane(a, c[a])) - pad[a];
          at(hi, a) = double(f.plane(a, c[a] + 1)) + pad[a];
        }
        if (triangle_overlaps_box(v[0], v[1], v[2], lo, hi)) fn(std::uint32_t(f.linear(c)));
      }
}

}  // namespace

std::array<std::uint32_t, 3> grid_resolution(const float extent[3], double cells) {
  cells = std::clamp(cells, 1.0, double(format::kGridMaxCells));
  bool active[3];
  for (int a = 0; a < 3; ++a) active[a] = extent[a] > 0.0f;
  // Cells per unit length s with s^k * (product of the k active extents) = cells; an axis
  // thinner than one such cell gets a single cell and the others share the budget.
  double s = 0;
  for (int round = 0; round < 3; ++round) {
    double volume = 1;
    int k = 0;
    for (int a = 0; a < 3; ++a)
      if (active[a]) volume *= extent[a], ++k;
    if (k == 0) break;
    s = std::pow(cells / volume, 1.0 / k);
    bool changed = false;
    for (int a = 0; a < 3; ++a)
      if (active[a] && extent[a] * s < 1.0) active[a] = false, changed = true;
    if (!changed) break;
  }
  std::array<std::uint32_t, 3> res{};
  for (int a = 0; a < 3; ++a)
    res[a] = active[a] ? std::uint32_t(std::clamp(std::llround(extent[a] * s), 1ll,
                                                  (long long)format::kGridMaxAxis))
                       : 1;
  while (std::uint64_t(res[0]) * res[1] * res[2] > format::kGridMaxCells) {
    const double shrink =
        std::cbrt(double(format::kGridMaxCells) / double(std::uint64_t(res[0]) * res[1] * res[2]));
    for (auto& r : res) r = std::max(1u, std::uint32_t(r * shrink));
  }
  return res;
}

GridFrame padded_frame(const format::Box3f& bounds, const std::array<std::uint32_t, 3>& res) {
  double largest = 0;
  for (int a = 0; a < 3; ++a)
    largest = std::max(largest, double(at(bounds.max, a)) - double(at(bounds.min, a)));
  GridFrame f{};
  for (int a = 0; a < 3; ++a) {
    const double lo = at(bounds.min, a), hi = at(bounds.max, a);
    const double pad =
        std::max({largest * 1e-4, std::max(std::fabs(lo), std::fabs(hi)) * 0x1p-18, 1e-30});
    f.lo[a] = float(lo - pad), f.hi[a] = float(hi + pad), f.res[a] = res[a];
  }
  return f;
}

CellLists build_cell_lists(const GridFrame& frame, std::span<const format::RayTriangle> triangles,
                           std::span<const std::uint32_t> ids, unsigned threads) {
  const auto pad = cell_padding(frame);
  // Count pass and prefix sums: each triangle's slots in a (triangle, cell) pair array.
  std::vector<std::uint64_t> start(ids.size() + 1, 0);
  parallel_for_batched(ids.size(), 1024, threads, [&](std::size_t k) {
    std::uint64_t n = 0;
    overlapped_cells(frame, pad, triangles[ids[k]], [&](std::uint32_t) { ++n; });
    start[k + 1] = n;
  });
  std::partial_sum(start.begin(), start.end(), start.begin());
  if (start.back() >= 0xFFFFFFFFull)
    throw std::runtime_error("grid: more than 2^32 - 1 cell references; lower the density");
  // Fill pass: each triangle writes its own slots.
  std::vector<std::uint32_t> pair_cell(start.back());
  parallel_for_batched(ids.size(), 1024, threads, [&](std::size_t k) {
    std::uint64_t slot = start[k];
    overlapped_cells(frame, pad, triangles[ids[k]],
                     [&](std::uint32_t c) { pair_cell[slot++] = c; });
  });
  // Counting sort by cell; the scatter runs in triangle order, so lists keep the order of ids.
  CellLists lists;
  lists.offsets.assign(frame.cell_count() + 1, 0);
  for (const std::uint32_t c : pair_cell) ++lists.offsets[c + 1];
  std::partial_sum(lists.offsets.begin(), lists.offsets.end(), lists.offsets.begin());
  lists.refs.resize(pair_cell.size());
  std::vector<std::uint32_t> next(lists.offsets.begin(), lists.offsets.end() - 1);
  for (std::size_t k = 0; k < ids.size(); ++k)
    for (std::uint64_t slot = start[k]; slot < start[k + 1]; ++slot)
      lists.refs[next[pair_cell[slot]]++] = ids[k];
  return lists;
}

CellLists build_top_level(const Scene& scene, const GridBuildOptions& options, FlatGrid& grid) {
  const auto& v = scene.positions;
  grid.triangles.reserve(scene.triangles.size());
  for (const format::Triangle& t : scene.triangles)
    grid.triangles.push_back({v[t.v[0]], v[t.v[1]], v[t.v[2]]});
  float extent[3];
  for (int a = 0; a < 3; ++a) extent[a] = at(scene.bounds.max, a) - at(scene.bounds.min, a);
  const double n = double(scene.triangles.size());
  grid.frame = padded_frame(scene.bounds, grid_resolution(extent, options.density * n));
  std::vector<std::uint32_t> ids(scene.triangles.size());
  std::iota(ids.begin(), ids.end(), 0u);
  return build_cell_lists(grid.frame, grid.triangles, ids, options.threads);
}

void measure_grid(FlatGrid& grid) {
  GridStatistics& s = grid.stats;
  s.cell_count = grid.offsets.size() - 1;
  s.reference_count = grid.refs.size();
  for (std::size_t c = 0; c < s.cell_count; ++c) {
    const std::uint32_t n = grid.offsets[c + 1] - grid.offsets[c];
    s.empty_cell_count += n == 0;
    s.largest_cell = std::max(s.largest_cell, n);
  }
  for (const format::LeafGrid& leaf : grid.leaves) s.top_empty_cell_count += leaf.res[0] == 0;
  const double n = double(grid.triangles.size());
  s.references_per_triangle = double(s.reference_count) / n;
  s.bytes_per_triangle = double(grid.offsets.size() * 4 + grid.refs.size() * 4 +
                                grid.leaves.size() * sizeof(format::LeafGrid) +
                                grid.triangles.size() * sizeof(format::RayTriangle)) /
                         n;
}

FlatGrid build_grid(const Scene& scene, const GridBuildOptions& options) {
  if (scene.triangles.empty()) throw std::runtime_error("grid: the scene has no triangles");
  FlatGrid grid;
  CellLists lists = build_top_level(scene, options, grid);
  grid.offsets = std::move(lists.offsets);
  grid.refs = std::move(lists.refs);
  measure_grid(grid);
  return grid;
}

}  // namespace kiln
