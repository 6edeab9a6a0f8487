// Surface voxelization brick by brick: triangles are binned to the bricks (128^3 voxels, in
// Morton order) their candidate voxels touch; each brick tests its triangles column by column
// along the triangle's dominant axis (only the few voxels the plane can reach in each column),
// then sorts its codes. Concatenating bricks in Morton order gives the global order, so no global
// sort and no dense grid is needed, and every brick is a pure function of its triangles.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "kiln/compiler/voxelizer.hpp"
#include "kiln/formats/voxel_grid.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln {

namespace {

constexpr std::uint32_t kBrickSide = 128;

struct VoxelRange {
  std::int64_t lo[3], hi[3];  // inclusive; empty when lo > hi on an axis
};

// Voxels whose closed box can meet the triangle's bounding box, clipped to `clip`.
VoxelRange candidate_range(const GridTriangle& t, const VoxelRange& clip) {
  VoxelRange r;
  for (int a = 0; a < 3; ++a) {
    const double lo =
        std::min({format::at(t.v[0], a), format::at(t.v[1], a), format::at(t.v[2], a)});
    const double hi =
        std::max({format::at(t.v[0], a), format::at(t.v[1], a), format::at(t.v[2], a)});
    // A box [k, k+1] touches a coordinate in [lo, hi] for k in [ceil(lo) - 1, floor(hi)].
    r.lo[a] = std::max(clip.lo[a], std::int64_t(std::ceil(lo)) - 1);
    r.hi[a] = std::min(clip.hi[a], std::int64_t(std::floor(hi)));
  }
  return r;
}

// Calls emit(x, y, z) for every voxel of `clip` the triangle touches.
template <class Emit>
void voxelize_triangle(const GridTriangle& t, const VoxelRange& clip, Emit emit) {
  const VoxelRange r = candidate_range(t, clip);
  if (r.lo[0] > r.hi[0] || r.lo[1] > r.hi[1] || r.lo[2] > r.hi[2]) return;
  const format::Double3 n = cross(t.v[1] - t.v[0], t.v[2] - t.v[0]);
  int a = 0;
  for (int i = 1; i < 3; ++i)
    if (std::fabs(format::at(n, i)) > std::fabs(format::at(n, a))) a = i;
  const double na = format::at(n, a), nu = format::at(n, (a + 1) % 3),
               nv = format::at(n, (a + 2) % 3);
  const int u = (a + 1) % 3, v = (a + 2) % 3;
  const double d = dot(n, t.v[0]);
  for (std::int64_t iu = r.lo[u]; iu <= r.hi[u]; ++iu)
    for (std::int64_t iv = r.lo[v]; iv <= r.hi[v]; ++iv) {
      // The plane's extent along `a` over the column's closed rectangle; one voxel of slack on
      // each side absorbs rounding, and the exact test below decides.
      double amin = INFINITY, amax = -INFINITY;
      for (const double cu : {double(iu), double(iu + 1)})
        for (const double cv : {double(iv), double(iv + 1)}) {
          const double at = (d - nu * cu - nv * cv) / na;
          amin = std::min(amin, at), amax = std::max(amax, at);
        }
      const std::int64_t lo = std::max(r.lo[a], std::int64_t(std::floor(amin)) - 1);
      const std::int64_t hi = std::min(r.hi[a], std::int64_t(std::floor(amax)) + 1);
      for (std::int64_t ia = lo; ia <= hi; ++ia) {
        std::int64_t c[3];
        c[a] = ia, c[u] = iu, c[v] = iv;
        if (triangle_touches_voxel(t, std::uint32_t(c[0]), std::uint32_t(c[1]),
                                   std::uint32_t(c[2])))
          emit(std::uint32_t(c[0]), std::uint32_t(c[1]), std::uint32_t(c[2]));
      }
    }
}

struct BrickOutput {
  std::vector<std::uint64_t> codes;
  std::vector<std::uint32_t> normals;
};

GridTriangle grid_triangle(const Scene& scene, const VoxelGrid& grid, std::uint32_t i) {
  const auto& tri = scene.triangles[i];
  return to_grid(grid, scene.positions[tri.v[0]], scene.positions[tri.v[1]],
                 scene.positions[tri.v[2]]);
}

// The cube as an inclusive voxel range.
VoxelRange range_of(const VoxelCube& cube) {
  VoxelRange r;
  for (int a = 0; a < 3; ++a)
    r.lo[a] = cube.origin[a], r.hi[a] = std::int64_t(cube.origin[a]) + cube.side - 1;
  return r;
}

// Each of `triangles`, in the given order, in the bin (Morton index within `cube`) of each brick
// of side `brick` its candidate voxels reach inside `cube`.
std::vector<std::vector<std::uint32_t>> bin_triangles(const Scene& scene, const VoxelGrid& grid,
                                                      const VoxelCube& cube,
                                                      std::span<const std::uint32_t> triangles,
                                                      std::uint32_t brick) {
  const std::uint32_t bricks_per_axis = cube.side / brick;
  const VoxelRange whole = range_of(cube);
  std::vector<std::vector<std::uint32_t>> bins(std::size_t(bricks_per_axis) * bricks_per_axis *
                                               bricks_per_axis);
  for (const std::uint32_t i : triangles) {
    const VoxelRange r = candidate_range(grid_triangle(scene, grid, i), whole);
    if (r.lo[0] > r.hi[0] || r.lo[1] > r.hi[1] || r.lo[2] > r.hi[2]) continue;
    std::uint32_t lo[3], hi[3];
    for (int a = 0; a < 3; ++a)
      lo[a] = std::uint32_t((r.lo[a] - whole.lo[a]) / brick),
      hi[a] = std::uint32_t((r.hi[a] - whole.lo[a]) / brick);
    for (std::uint32_t bz = lo[2]; bz <= hi[2]; ++bz)
      for (std::uint32_t by = lo[1]; by <= hi[1]; ++by)
        for (std::uint32_t bx = lo[0]; bx <= hi[0]; ++bx)
          bins[format::morton_code(bx, by, bz)].push_back(i);
  }
  return bins;
}

// The voxels of brick `b` (Morton index within `cube`) that `triangles` touch, sorted, and with
// `normals` the octahedral sum of their triangles' unit normals.
BrickOutput voxelize_brick(const Scene& scene, const VoxelGrid& grid, const VoxelCube& cube,
                           std::uint32_t brick, std::size_t b,
                           std::span<const std::uint32_t> triangles, bool normals) {
  const std::uint32_t local[3] = {format::compact_bits(b), format::compact_bits(b >> 1),
                                  format::compact_bits(b >> 2)};
  VoxelRange clip;
  for (int a = 0; a < 3; ++a)
    clip.lo[a] = std::int64_t(cube.origin[a]) + std::int64_t(local[a]) * brick,
    clip.hi[a] = clip.lo[a] + brick - 1;
  // (code, triangle) pairs: sorting them fixes the order normals are summed in.
  std::vector<std::pair<std::uint64_t, std::uint32_t>> hits;
  for (const std::uint32_t i : triangles)
    voxelize_triangle(grid_triangle(scene, grid, i), clip,
                      [&](std::uint32_t x, std::uint32_t y, std::uint32_t z) {
                        hits.emplace_back(format::morton_code(x, y, z), i);
                      });
  std::sort(hits.begin(), hits.end());
  BrickOutput result;
  for (std::size_t k = 0; k < hits.size();) {
    std::size_t end = k;
    double sum[3] = {0, 0, 0};
    for (; end < hits.size() && hits[end].first == hits[k].first; ++end) {
      if (!normals) continue;
      const auto& tri = scene.triangles[hits[end].second];
      const format::Double3 a = to_d(scene.positions[tri.v[0]]),
                            b2 = to_d(scene.positions[tri.v[1]]),
                            c = to_d(scene.positions[tri.v[2]]);
      const format::Double3 nrm = cross(b2 - a, c - a);
      const double length = std::sqrt(dot(nrm, nrm));
      for (int axis = 0; axis < 3; ++axis) sum[axis] += format::at(nrm, axis) / length;
    }
    result.codes.push_back(hits[k].first);
    if (normals)
      result.normals.push_back(
          format::encode_octahedral(float(sum[0]), float(sum[1]), float(sum[2])));
    k = end;
  }
  return result;
}

// Bricks in Morton order give the global Morton order; each brick is released once copied.
void concatenate_bricks(std::vector<BrickOutput>& bricks, bool normals, Voxels& out) {
  std::size_t total = 0;
  for (const auto& b : bricks) total += b.codes.size();
  out.codes.reserve(total);
  if (normals) out.normals.reserve(total);
  for (auto& b : bricks) {
    out.codes.insert(out.codes.end(), b.codes.begin(), b.codes.end());
    out.normals.insert(out.normals.end(), b.normals.begin(), b.normals.end());
    b = {};
  }
}

}  // namespace

VoxelGrid fit_voxel_grid(const format::Box3f& bounds, std::uint32_t resolution) {
  const double lo[3] = {bounds.min.x, bounds.min.y, bounds.min.z};
  const double hi[3] = {bounds.max.x, bounds.max.y, bounds.max.z};
  double side = 0;
  for (int a = 0; a < 3; ++a) side = std::max(side, hi[a] - lo[a]);
  if (!(side > 0)) side = 1;  // a single point: any cube around it
  VoxelGrid grid;
  grid.resolution = resolution;
  // Centred, but never past the bounds: rounding must not leave a face of the scene outside the
  // grid (a triangle lying in it would then touch no voxel). The voxel grows by a few ulps when
  // needed so the max corner, as to_grid computes it, is at most `resolution`.
  double size = side / resolution;
  for (int a = 0; a < 3; ++a) {
    grid.origin[a] = std::min(lo[a], 0.5 * (lo[a] + hi[a]) - 0.5 * side);
    size = std::max(size, (hi[a] - grid.origin[a]) / resolution);
  }
  for (int a = 0, tries = 0; a < 3 && tries < 64;)
    if ((hi[a] - grid.origin[a]) / size > resolution || grid.origin[a] + size * resolution < hi[a])
      size = std::nextafter(size, INFINITY), ++tries;
    else
      ++a;
  grid.voxel_size = size;
  return grid;
}

GridTriangle to_grid(const VoxelGrid& grid, const format::Float3& a, const format::Float3& b,
                     const format::Float3& c) {
  GridTriangle t;
  const format::Float3* corners[3] = {&a, &b, &c};
  for (int i = 0; i < 3; ++i)
    t.v[i] = {(double(corners[i]->x) - grid.origin[0]) / grid.voxel_size,
              (double(corners[i]->y) - grid.origin[1]) / grid.voxel_size,
              (double(corners[i]->z) - grid.origin[2]) / grid.voxel_size};
  return t;
}

bool triangle_touches_voxel(const GridTriangle& t, std::uint32_t x, std::uint32_t y,
                            std::uint32_t z) {
  const format::Double3 lo{double(x), double(y), double(z)};
  const format::Double3 hi{double(x) + 1, double(y) + 1, double(z) + 1};
  return triangle_overlaps_box(t.v[0], t.v[1], t.v[2], lo, hi);
}

bool is_valid_cube(const VoxelGrid& grid, const VoxelCube& cube) {
  if (cube.side < 4 || (cube.side & (cube.side - 1)) != 0 || cube.side > grid.resolution)
    return false;
  for (const std::uint32_t o : cube.origin)
    if (o % cube.side != 0 || std::uint64_t(o) + cube.side > grid.resolution) return false;
  return true;
}

std::vector<std::uint32_t> triangles_reaching(const Scene& scene, const VoxelGrid& grid,
                                              const VoxelCube& cube) {
  const VoxelRange clip = range_of(cube);
  std::vector<std::uint32_t> out;
  for (std::uint32_t i = 0; i < scene.triangles.size(); ++i) {
    const VoxelRange r = candidate_range(grid_triangle(scene, grid, i), clip);
    if (r.lo[0] <= r.hi[0] && r.lo[1] <= r.hi[1] && r.lo[2] <= r.hi[2]) out.push_back(i);
  }
  return out;
}

Voxels voxelize_surface_cube(const Scene& scene, const VoxelGrid& grid, const VoxelCube& cube,
                             std::span<const std::uint32_t> triangles, bool normals,
                             unsigned threads) {
  if (!is_valid_cube(grid, cube)) throw std::invalid_argument("voxel cube outside the grid");
  Voxels out;
  out.grid = grid;
  const std::uint32_t brick = std::min(cube.side, kBrickSide);
  std::vector<std::vector<std::uint32_t>> bins = bin_triangles(scene, grid, cube, triangles, brick);
  std::vector<BrickOutput> bricks(bins.size());
  parallel_for(bins.size(), threads, [&](std::size_t b) {
    if (bins[b].empty()) return;
    bricks[b] = voxelize_brick(scene, grid, cube, brick, b, bins[b], normals);
    std::vector<std::uint32_t>().swap(bins[b]);
  });
  concatenate_bricks(bricks, normals, out);
  return out;
}

VoxelLeaves voxelize_surface_leaves(const Scene& scene, const VoxelGrid& grid,
                                    const VoxelCube& cube, std::span<const std::uint32_t> triangles,
                                    unsigned threads) {
  return leaves_of(voxelize_surface_cube(scene, grid, cube, triangles, false, threads).codes);
}

Voxels voxelize_surface(const Scene& scene, const VoxelizeOptions& options) {
  const std::uint32_t n = options.resolution;
  if (!format::is_valid_voxel_resolution(n))
    throw std::invalid_argument("--resolution " + std::to_string(n) +
                                " must be a power of two in " +
                                std::to_string(format::kVoxelMinResolution) + ".." +
                                std::to_string(format::kVoxelMaxResolution));
  const VoxelGrid grid = fit_voxel_grid(scene.bounds, n);
  std::vector<std::uint32_t> all(scene.triangles.size());
  for (std::uint32_t i = 0; i < all.size(); ++i) all[i] = i;
  return voxelize_surface_cube(scene, grid, VoxelCube{{0, 0, 0}, n}, all, options.normals,
                               options.threads);
}

}  // namespace kiln
