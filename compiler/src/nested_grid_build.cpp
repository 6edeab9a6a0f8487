// The two-level grid builder (Kalojanov, Billeter & Slusallek, "Two-Level Grids for Ray Tracing
// on GPUs", 2011): a coarse top grid by the density rule, then in every occupied top cell its own
// grid over the cell's box, sized by the density rule for the cell's triangle count. Both levels
// use the uniform grid's list builder; the leaf grids are built in parallel, one per top cell,
// each into its own slot, and concatenated in top-cell order.
#include <algorithm>
#include <numeric>
#include <stdexcept>

#include "kiln/compiler/grid_builder.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln {

namespace {

// All leaf grids together hold at most this many cells (1 GiB of offsets); beyond it the leaf
// density is lowered uniformly.
constexpr double kMaxLeafCells = double(1u << 28);

// Appends one leaf grid's lists to the flat arrays.
void append_leaf(FlatGrid& grid, const CellLists& lists) {
  const std::uint64_t base = grid.refs.size();
  if (base + lists.refs.size() >= 0xFFFFFFFFull)
    throw std::runtime_error("nested grid: more than 2^32 - 1 cell references");
  for (std::size_t c = 1; c < lists.offsets.size(); ++c)
    grid.offsets.push_back(std::uint32_t(base + lists.offsets[c]));
  grid.refs.insert(grid.refs.end(), lists.refs.begin(), lists.refs.end());
}

}  // namespace

FlatGrid build_nested_grid(const Scene& scene, const GridBuildOptions& options) {
  if (scene.triangles.empty()) throw std::runtime_error("nested grid: the scene has no triangles");
  FlatGrid grid;
  grid.levels = 2;
  const CellLists top = build_top_level(scene, options, grid);

  const std::uint64_t top_cells = grid.frame.cell_count();
  const double leaf_density =
      std::min(double(options.leaf_density), kMaxLeafCells / std::max<double>(top.refs.size(), 1));
  std::vector<CellLists> leaf_lists(top_cells);
  grid.leaves.assign(top_cells, format::LeafGrid{{0, 0, 0}, 0});
  parallel_for(top_cells, options.threads, [&](std::size_t i) {
    const std::span<const std::uint32_t> members(top.refs.data() + top.offsets[i],
                                                 top.offsets[i + 1] - top.offsets[i]);
    if (members.empty()) return;
    std::uint32_t c[3] = {std::uint32_t(i % grid.frame.res[0]),
                          std::uint32_t(i / grid.frame.res[0] % grid.frame.res[1]),
                          std::uint32_t(i / grid.frame.res[0] / grid.frame.res[1])};
    const GridFrame cell = grid.frame.cell_frame(c, grid.frame.res);
    const float cell_extent[3] = {cell.hi[0] - cell.lo[0], cell.hi[1] - cell.lo[1],
                                  cell.hi[2] - cell.lo[2]};
    const auto res = grid_resolution(cell_extent, leaf_density * double(members.size()));
    const GridFrame leaf = grid.frame.cell_frame(c, res.data());
    std::copy(res.begin(), res.end(), grid.leaves[i].res);
    leaf_lists[i] = build_cell_lists(leaf, grid.triangles, members, 1);
  });

  grid.offsets.push_back(0);
  std::uint64_t cells = 0;
  for (std::uint64_t i = 0; i < top_cells; ++i) {
    grid.leaves[i].first_cell = std::uint32_t(cells);
    if (grid.leaves[i].res[0] == 0) continue;
    cells += leaf_lists[i].offsets.size() - 1;
    append_leaf(grid, leaf_lists[i]);
    leaf_lists[i] = {};
  }
  measure_grid(grid);
  return grid;
}

}  // namespace kiln
