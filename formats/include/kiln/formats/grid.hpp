// On-disk layout of the uniform grid ("grid") and the two-level grid ("nested-grid"):
// compressed-row cell lists (one offset per cell plus one, then the triangle ids of every cell in
// cell order), one copy of every triangle's corners by primitive id, and for the two-level grid
// one descriptor per top cell naming its own grid's resolution and first cell.
#pragma once

#include <cstdint>

#include "kiln/formats/container.hpp"
#include "kiln/formats/ray_triangle.hpp"

namespace kiln::format {

inline constexpr std::uint32_t kSectionGridOffsets = fourcc('G', 'R', 'D', 'O');
inline constexpr std::uint32_t kSectionGridRefs = fourcc('G', 'R', 'D', 'R');
inline constexpr std::uint32_t kSectionGridTriangles = fourcc('G', 'R', 'D', 'T');
inline constexpr std::uint32_t kSectionGridLeaves = fourcc('G', 'R', 'D', 'L');

// Cells of a grid are numbered x fastest, then y, then z. Offsets are u32: a grid holds at most
// 2^32 - 1 references (the builder refuses more).
// The resolution of one axis, and the cells of one grid (the uniform grid, the top grid or one
// leaf grid): memory stays bounded (16 Mi cells = 64 MiB of offsets) whatever λ asks for. The
// builder also keeps all leaf grids together under 2^28 cells.
inline constexpr std::uint32_t kGridMaxAxis = 1024;
inline constexpr std::uint64_t kGridMaxCells = std::uint64_t(1) << 24;

// A top cell of the two-level grid: the resolution of its own grid (0 0 0: an empty cell) and
// the index of its first cell among all leaf cells; its box is the top cell's box.
struct LeafGrid {
  std::uint32_t res[3];
  std::uint32_t first_cell;
};
static_assert(sizeof(LeafGrid) == 16);

// Plane i (0..res) of an axis from lo to hi: the builder and the traversal compute cell
// boundaries with this one formula (the traversal hoists the cell size out of its loop), so they
// agree on every cell's box.
inline float grid_cell_size(float lo, float hi, std::uint32_t res) {
  return (hi - lo) / float(res);
}
inline float grid_plane_at(float lo, float hi, float cell_size, std::uint32_t i,
                           std::uint32_t res) {
  return i >= res ? hi : lo + float(i) * cell_size;
}
inline float grid_plane(float lo, float hi, std::uint32_t i, std::uint32_t res) {
  return grid_plane_at(lo, hi, grid_cell_size(lo, hi, res), i, res);
}

}  // namespace kiln::format
