// Builders of the uniform grid and the two-level grid (Kalojanov, Billeter & Slusallek 2011)
// producing the mapped layout of formats/grid.hpp, and the pieces they share: the density rule
// for a grid's resolution and the compressed-row cell lists of a set of triangles over a grid.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "kiln/compiler/scene.hpp"
#include "kiln/formats/geometry.hpp"
#include "kiln/formats/grid.hpp"
#include "kiln/runtime/grid_dda.hpp"

namespace kiln {

struct GridBuildOptions {
  // λ: about λ N cells over N triangles (the top grid's, for two levels). Defaults (here and in
  // grid_entry.cpp): the lowest mean traversal cost per ray (cell visits + triangle tests, from
  // `kiln render --mode heatmap --compare ... --json`, 320x200 camera rays) on the Stanford bunny
  // and the 100k dragon, over λ in {0.5 .. 16} for the uniform grid (λ = 2) and top λ in
  // {1/64 .. 1} x leaf λ in {1, 2, 4} for the two-level grid (1/16 and 2); docs/BENCHMARKS.md.
  float density = 2.0f;       // uniform grid; the two-level grid's top default is 1/16
  float leaf_density = 2.0f;  // two levels: about λ_leaf n cells in a top cell holding n triangles
  unsigned threads = 0;       // never changes the result
};

struct GridStatistics {
  std::uint64_t cell_count = 0, empty_cell_count = 0, top_empty_cell_count = 0;
  std::uint64_t reference_count = 0;
  std::uint32_t largest_cell = 0;
  double references_per_triangle = 0, bytes_per_triangle = 0;
};

struct FlatGrid {
  std::uint8_t levels = 1;
  GridFrame frame{};                           // the (top) grid
  std::vector<std::uint32_t> offsets, refs;    // cell lists: the grid's, or every leaf grid's
  std::vector<format::LeafGrid> leaves;        // two levels: one per top cell
  std::vector<format::RayTriangle> triangles;  // every triangle's corners, by primitive id
  GridStatistics stats;
};

/// Compressed-row lists: cell c holds refs[offsets[c] .. offsets[c + 1]).
struct CellLists {
  std::vector<std::uint32_t> offsets, refs;
};

/// The density rule (Cleary & Wyvill 1988; pbrt's grid): cells as cubic as possible, about
/// `cells` of them over a box of these extents; an axis too thin for one cell gets one, each axis
/// is clamped to 1..kGridMaxAxis and the total to kGridMaxCells.
std::array<std::uint32_t, 3> grid_resolution(const float extent[3], double cells);

/// A grid's box around `bounds`: padded on every side so that no axis is flat and rounding at
/// the border never loses a triangle.
GridFrame padded_frame(const format::Box3f& bounds, const std::array<std::uint32_t, 3>& res);

/// The lists of triangles `ids` (ascending) over `frame`: triangle i in every cell whose closed
/// box, padded by a thousandth of a cell and a few units in the last place, it meets by the
/// separating-axis test (only cells in its bounding box's range are tested). A list keeps the
/// order of `ids`. In parallel on `threads`; the result never depends on them. Throws
/// std::runtime_error when the lists would hold 2^32 or more references.
CellLists build_cell_lists(const GridFrame& frame, std::span<const format::RayTriangle> triangles,
                           std::span<const std::uint32_t> ids, unsigned threads);

FlatGrid build_grid(const Scene& scene, const GridBuildOptions& options);
FlatGrid build_nested_grid(const Scene& scene, const GridBuildOptions& options);

/// Shared by both builders, the top level: `grid`'s triangle copies (by primitive id) and its
/// frame of about density x N cells over the scene bounds; returns that frame's cell lists.
CellLists build_top_level(const Scene& scene, const GridBuildOptions& options, FlatGrid& grid);
/// Cell, empty-cell and reference statistics of finished lists, and bytes per triangle.
void measure_grid(FlatGrid& grid);

}  // namespace kiln
