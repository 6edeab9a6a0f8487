// Conservative surface voxelization on a cubic grid fitted to the scene: a voxel is set when a
// triangle meets its closed box (separating-axis test, Akenine-Moller 2001). Sparse: the output
// is the sorted Morton codes of the set voxels, produced brick by brick, never a dense N^3 array.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "kiln/compiler/scene.hpp"
#include "kiln/runtime/triangle_geometry.hpp"
#include "kiln/runtime/voxel_grid.hpp"

namespace kiln {

// Voxel (x, y, z) spans origin + [x, x+1] * voxel_size (likewise y, z), 0 <= x, y, z < resolution.
struct VoxelGrid {
  std::array<double, 3> origin{};
  double voxel_size = 1;
  std::uint32_t resolution = 0;
};

// The grid as the runtime's voxel views take it.
inline VoxelGridFrame frame_of(const VoxelGrid& g) {
  VoxelGridFrame frame;
  for (int a = 0; a < 3; ++a) frame.origin[a] = g.origin[a];
  frame.voxel_size = g.voxel_size;
  frame.resolution = g.resolution;
  return frame;
}

// The cube of side = the bounds' largest extent, centred on the bounds (no padding: a triangle
// on the bounds' faces sets the boundary voxels, whose closed boxes reach the faces). Rounding is
// resolved outwards: the origin never exceeds the bounds' min and the voxel size grows by a few
// ulps when needed, so every corner of the bounds lies in [0, resolution] in grid units.
VoxelGrid fit_voxel_grid(const format::Box3f& bounds, std::uint32_t resolution);

// A triangle's corners in grid units (voxel (x, y, z) is the box [x, x+1] x [y, y+1] x [z, z+1]).
struct GridTriangle {
  format::Double3 v[3];
};
GridTriangle to_grid(const VoxelGrid& grid, const format::Float3& a, const format::Float3& b,
                     const format::Float3& c);

// The voxelizer's one predicate, shared with every brute-force check.
bool triangle_touches_voxel(const GridTriangle& t, std::uint32_t x, std::uint32_t y,
                            std::uint32_t z);

/// Which code decides the voxels of small triangles (candidate range at most 12 voxels on every
/// axis; larger ones always take the column walk): the column walk (portable), or the
/// brute-force window kernel with AVX2 or AVX-512 (run-time CPU dispatch). Every kernel gives
/// the same voxels. kAuto: KILN_VOXEL_KERNEL (columns, avx2 or avx512) when set, else the widest
/// kernel this CPU runs.
enum class VoxelKernel { kAuto, kColumns, kAvx2, kAvx512 };
const char* voxel_kernel_name(VoxelKernel kernel);
bool voxel_kernel_supported(VoxelKernel kernel);
/// Every later voxelization in this process uses `kernel` (kAuto: the default again). Throws
/// std::invalid_argument when this CPU cannot run it.
void set_voxel_kernel(VoxelKernel kernel);
/// The kernel voxelizations use now (never kAuto). Throws std::invalid_argument when
/// KILN_VOXEL_KERNEL names no kernel or one this CPU cannot run.
VoxelKernel voxel_kernel();

struct VoxelizeOptions {
  std::uint32_t resolution = 512;
  bool normals = false;  // also average the touching triangles' normals per voxel
  unsigned threads = 0;  // never changes the result
  bool solid = false;    // also the interior voxels (solid_leaves); closed meshes only
};

struct Voxels {
  VoxelGrid grid;
  std::vector<std::uint64_t> codes;    // Morton codes (formats/voxel_grid.hpp), ascending, unique
  std::vector<std::uint32_t> normals;  // octahedral, parallel to codes; empty unless asked
};

// Throws std::invalid_argument for a resolution that is not a power of two in
// [kVoxelMinResolution, kVoxelMaxResolution].
Voxels voxelize_surface(const Scene& scene, const VoxelizeOptions& options);

/// The voxel builders' memory budget when none is given (--memory-budget auto): half the
/// physical memory, at most 8 GiB (1 GiB when the machine does not say).
std::uint64_t default_memory_budget();

/// A cube of grid cells, [origin, origin + side) on each axis: side a power of two >= 4 and
/// <= the resolution, each origin a multiple of side. Out-of-core builds work cube by cube.
struct VoxelCube {
  std::array<std::uint32_t, 3> origin{};
  std::uint32_t side = 0;
};
bool is_valid_cube(const VoxelGrid& grid, const VoxelCube& cube);

/// The triangles (indices, ascending) whose candidate voxels reach `cube`: a superset of those
/// that touch a voxel of it.
std::vector<std::uint32_t> triangles_reaching(const Scene& scene, const VoxelGrid& grid,
                                              const VoxelCube& cube);

/// The voxels of `cube` that `triangles` touch, as voxelize_surface gives them for the whole grid
/// (global Morton codes, ascending; normals when asked). Pass every triangle that can reach the
/// cube (triangles_reaching); extra ones cost time only. Throws std::invalid_argument for a cube
/// that is_valid_cube refuses.
Voxels voxelize_surface_cube(const Scene& scene, const VoxelGrid& grid, const VoxelCube& cube,
                             std::span<const std::uint32_t> triangles, bool normals,
                             unsigned threads);

// Voxels as 4x4x4 blocks: 8 bytes per 64 voxels, so a solid interior stays small.
struct VoxelLeaves {
  std::vector<std::uint64_t> keys;   // Morton code >> 6 of each non-empty block, ascending
  std::vector<std::uint64_t> masks;  // bit i: the voxel with Morton index i inside the block
  std::uint64_t voxel_count = 0;
};
VoxelLeaves leaves_of(std::span<const std::uint64_t> codes);

/// Bytes the voxelizer holds to bin `triangles` triangles into the bricks of a cube of `side`
/// (its per-brick offsets and per-range counters, and about 12 bytes per triangle), besides the
/// voxels it outputs.
double voxelizer_binning_bytes(std::uint32_t side, std::size_t triangles);

/// The surface voxels of `cube` as 4x4x4 blocks with global keys: equal to
/// leaves_of(voxelize_surface_cube(scene, grid, cube, triangles, false, threads).codes), and for
/// the whole grid to leaves_of(voxelize_surface(...).codes), without the per-voxel codes.
VoxelLeaves voxelize_surface_leaves(const Scene& scene, const VoxelGrid& grid,
                                    const VoxelCube& cube, std::span<const std::uint32_t> triangles,
                                    unsigned threads);

// The surface voxels plus every voxel whose centre lies inside the mesh: along each column of
// voxel centres parallel to z, the crossings with the triangles (one per triangle whose xy
// projection holds the column, shared edges counted once) are paired in order, and the centres
// between a pair are inside. Meaningful for closed meshes; an unpaired last crossing is ignored.
// Brick by brick like the surface; the bricks' leaf masks are concatenated in Morton order.
VoxelLeaves solid_leaves(const Scene& scene, const VoxelGrid& grid,
                         std::span<const std::uint64_t> surface_codes, unsigned threads);

}  // namespace kiln
