// Solid voxelization: surface voxels plus the interior found by crossing parity along z columns.
#include <algorithm>
#include <bit>
#include <cmath>

#include "kiln/compiler/voxelizer.hpp"
#include "kiln/formats/voxel_grid.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln {

namespace {

constexpr std::uint32_t kBrickSide = 128;

// Whether the column through (px, py) passes the triangle's xy projection. A column on a shared
// edge belongs to one side only (the top-left rule of rasterisers), so closed meshes cross it
// once; a column on a vertex shared by several triangles likewise counts once.
bool column_crosses(const GridTriangle& t, double px, double py) {
  double ax = t.v[0].x, ay = t.v[0].y, bx = t.v[1].x, by = t.v[1].y, cx = t.v[2].x, cy = t.v[2].y;
  const double area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
  if (area == 0) return false;                         // seen edge-on: no crossing
  if (area < 0) std::swap(bx, cx), std::swap(by, cy);  // make it counter-clockwise
  const double xs[3] = {ax, bx, cx}, ys[3] = {ay, by, cy};
  for (int i = 0; i < 3; ++i) {
    const double x0 = xs[i], y0 = ys[i], x1 = xs[(i + 1) % 3], y1 = ys[(i + 1) % 3];
    const double e = (x1 - x0) * (py - y0) - (y1 - y0) * (px - x0);
    if (e < 0) return false;
    if (e == 0) {
      const double dx = x1 - x0, dy = y1 - y0;
      const bool top_left = dy < 0 || (dy == 0 && dx > 0);
      if (!top_left) return false;
    }
  }
  return true;
}

}  // namespace

VoxelLeaves leaves_of(std::span<const std::uint64_t> codes) {
  VoxelLeaves leaves;
  leaves.voxel_count = codes.size();
  for (std::size_t i = 0; i < codes.size();) {
    const std::uint64_t key = codes[i] >> 6;
    std::uint64_t mask = 0;
    for (; i < codes.size() && codes[i] >> 6 == key; ++i)
      mask |= std::uint64_t{1} << (codes[i] & 63);
    leaves.keys.push_back(key);
    leaves.masks.push_back(mask);
  }
  return leaves;
}

VoxelLeaves solid_leaves(const Scene& scene, const VoxelGrid& grid,
                         std::span<const std::uint64_t> surface_codes, unsigned threads) {
  const std::uint32_t n = grid.resolution;
  const std::uint32_t brick = std::min(n, kBrickSide);
  const std::uint32_t per_axis = n / brick;
  const std::uint32_t brick_bits = 3 * std::uint32_t(std::countr_zero(brick));  // code bits inside

  // Bin triangles to the brick columns whose voxel-centre columns their xy bounds reach.
  std::vector<std::vector<std::uint32_t>> bins(std::size_t(per_axis) * per_axis);
  std::vector<GridTriangle> grid_triangles(scene.triangles.size());
  for (std::uint32_t i = 0; i < scene.triangles.size(); ++i) {
    const auto& tri = scene.triangles[i];
    const GridTriangle t = grid_triangles[i] = to_grid(
        grid, scene.positions[tri.v[0]], scene.positions[tri.v[1]], scene.positions[tri.v[2]]);
    const double x0 = std::min({t.v[0].x, t.v[1].x, t.v[2].x}) - 0.5;
    const double x1 = std::max({t.v[0].x, t.v[1].x, t.v[2].x}) - 0.5;
    const double y0 = std::min({t.v[0].y, t.v[1].y, t.v[2].y}) - 0.5;
    const double y1 = std::max({t.v[0].y, t.v[1].y, t.v[2].y}) - 0.5;
    const auto lo_x = std::max<std::int64_t>(0, std::int64_t(std::ceil(x0)));
    const auto hi_x = std::min<std::int64_t>(n - 1, std::int64_t(std::floor(x1)));
    const auto lo_y = std::max<std::int64_t>(0, std::int64_t(std::ceil(y0)));
    const auto hi_y = std::min<std::int64_t>(n - 1, std::int64_t(std::floor(y1)));
    if (lo_x > hi_x || lo_y > hi_y) continue;
    for (std::int64_t by = lo_y / brick; by <= hi_y / brick; ++by)
      for (std::int64_t bx = lo_x / brick; bx <= hi_x / brick; ++bx)
        bins[std::size_t(by) * per_axis + std::size_t(bx)].push_back(i);
  }

  struct BrickLeaves {
    std::vector<std::uint64_t> keys, masks;
  };
  std::vector<BrickLeaves> bricks(std::size_t(per_axis) * per_axis * per_axis);
  parallel_for(bins.size(), threads, [&](std::size_t column) {
    const std::uint32_t bx = std::uint32_t(column % per_axis),
                        by = std::uint32_t(column / per_axis);
    // Crossings of every voxel-centre column of this brick column: (local column, z).
    std::vector<std::pair<std::uint32_t, double>> crossings;
    for (const std::uint32_t i : bins[column]) {
      const GridTriangle& t = grid_triangles[i];
      const format::Double3 nrm = cross(t.v[1] - t.v[0], t.v[2] - t.v[0]);
      if (nrm.z == 0) continue;
      const double d = dot(nrm, t.v[0]);
      const auto clamp = [&](double v, std::int64_t lo, std::int64_t hi) {
        return std::clamp<std::int64_t>(std::int64_t(v), lo, hi);
      };
      const std::int64_t x_lo = std::int64_t(bx) * brick, y_lo = std::int64_t(by) * brick;
      const std::int64_t x_hi = x_lo + brick - 1, y_hi = y_lo + brick - 1;
      const std::int64_t cx0 =
          clamp(std::ceil(std::min({t.v[0].x, t.v[1].x, t.v[2].x}) - 0.5), x_lo, x_hi + 1);
      const std::int64_t cx1 =
          clamp(std::floor(std::max({t.v[0].x, t.v[1].x, t.v[2].x}) - 0.5), x_lo - 1, x_hi);
      const std::int64_t cy0 =
          clamp(std::ceil(std::min({t.v[0].y, t.v[1].y, t.v[2].y}) - 0.5), y_lo, y_hi + 1);
      const std::int64_t cy1 =
          clamp(std::floor(std::max({t.v[0].y, t.v[1].y, t.v[2].y}) - 0.5), y_lo - 1, y_hi);
      for (std::int64_t y = cy0; y <= cy1; ++y)
        for (std::int64_t x = cx0; x <= cx1; ++x) {
          const double px = double(x) + 0.5, py = double(y) + 0.5;
          if (!column_crosses(t, px, py)) continue;
          const double z = (d - nrm.x * px - nrm.y * py) / nrm.z;
          crossings.emplace_back(std::uint32_t((y - y_lo) * brick + (x - x_lo)), z);
        }
    }
    std::sort(crossings.begin(), crossings.end());
    std::vector<std::uint64_t> masks(std::size_t(brick) * brick * brick / 64);
    for (std::uint32_t bz = 0; bz < per_axis; ++bz) {
      std::fill(masks.begin(), masks.end(), 0);
      const std::uint64_t brick_code = format::morton_code(bx, by, bz);
      const std::uint64_t first = brick_code << brick_bits, last = (brick_code + 1) << brick_bits;
      const auto begin = std::lower_bound(surface_codes.begin(), surface_codes.end(), first);
      for (auto it = begin; it != surface_codes.end() && *it < last; ++it) {
        const std::uint64_t local = *it - first;
        masks[local >> 6] |= std::uint64_t{1} << (local & 63);
      }
      const double z_lo = double(bz) * brick;
      for (std::size_t k = 0; k < crossings.size();) {
        std::size_t end = k;
        while (end < crossings.size() && crossings[end].first == crossings[k].first) ++end;
        const std::uint32_t lx = crossings[k].first % brick, ly = crossings[k].first / brick;
        for (std::size_t p = k; p + 1 < end; p += 2) {
          // Centres z + 0.5 in [z0, z1], clipped to this brick.
          const double z0 = crossings[p].second - z_lo, z1 = crossings[p + 1].second - z_lo;
          const auto from = std::max<std::int64_t>(0, std::int64_t(std::ceil(z0 - 0.5)));
          const auto to = std::min<std::int64_t>(brick - 1, std::int64_t(std::floor(z1 - 0.5)));
          for (std::int64_t lz = from; lz <= to; ++lz) {
            const std::uint64_t local = format::morton_code(lx, ly, std::uint32_t(lz));
            masks[local >> 6] |= std::uint64_t{1} << (local & 63);
          }
        }
        k = end;
      }
      BrickLeaves& out = bricks[brick_code];
      for (std::size_t leaf = 0; leaf < masks.size(); ++leaf)
        if (masks[leaf] != 0) {
          out.keys.push_back((first >> 6) + leaf);
          out.masks.push_back(masks[leaf]);
        }
    }
  });
  VoxelLeaves leaves;
  for (auto& b : bricks) {
    leaves.keys.insert(leaves.keys.end(), b.keys.begin(), b.keys.end());
    leaves.masks.insert(leaves.masks.end(), b.masks.begin(), b.masks.end());
    b = {};
  }
  for (const std::uint64_t m : leaves.masks) leaves.voxel_count += std::popcount(m);
  return leaves;
}

}  // namespace kiln
