// Top-down ESVO construction. The surface cells come from the voxelizer (the same conservative
// cells every voxel structure holds), so a voxel exists exactly where a surface cell lies below it;
// the triangles are narrowed to each child by the voxelizer's separating-axis test, clipped to it,
// and fitted with a contour. A voxel stops subdividing when its contour slab stays within reach
// of the surface cells (esvo_contour.hpp), or at the finest level.
//
// The top levels form block 0; every group of children at the block level starts its own block,
// built as an independent task, so the result never depends on the thread count.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <iomanip>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>

#include "esvo_contour.hpp"
#include "esvo_tree.hpp"
#include "kiln/formats/voxel_grid.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln {

namespace {

using esvo::Cube;
using esvo::Slab;
using esvo::TempBlock;
using esvo::TempNode;

constexpr std::uint32_t kMaxBlockLevel = 4;  // up to 8^3 blocks: enough tasks to balance

struct Context {
  const Scene* scene = nullptr;
  VoxelGrid grid;
  std::uint32_t levels = 0, block_level = 0, reach = 0;
  bool contours = true;
  std::span<const std::uint64_t> codes;
  std::vector<GridTriangle> triangles;        // in grid units
  std::vector<format::Double3> unit_normals;  // as the voxelizer sums them
  std::vector<std::array<double, 4>> colors;  // per triangle: its corners' mean RGBA, 0..255
};

// A voxel whose children are still to be decided.
struct Work {
  Cube cube;
  std::uint32_t level = 0;
  std::vector<std::uint32_t> triangles;  // those touching the cube, ascending
  std::size_t code_lo = 0, code_hi = 0;  // its surface cells in Context::codes
  std::optional<Slab> slab;              // its own contour, if any
};

std::uint64_t cube_code(const Cube& c) {
  return format::morton_code(c.corner[0], c.corner[1], c.corner[2]);
}

// The mean of `count` summed RGBA colours, rounded, packed r | g << 8 | b << 16 | a << 24.
std::uint32_t mean_rgba8(const std::array<double, 4>& sum, std::size_t count) {
  std::uint32_t packed = 0;
  for (int k = 0; k < 4; ++k)
    packed |= std::uint32_t(count == 0 ? 0 : std::lround(sum[k] / double(count))) << (8 * k);
  return packed;
}

bool touches(const GridTriangle& t, const Cube& c) {
  const format::Double3 lo{double(c.corner[0]), double(c.corner[1]), double(c.corner[2])};
  const format::Double3 hi{lo.x + c.side, lo.y + c.side, lo.z + c.side};
  return triangle_overlaps_box(t.v[0], t.v[1], t.v[2], lo, hi);
}

// Child `octant` of `w` with its range of surface cells, or nothing when it holds none.
std::optional<Work> child_work(const Context& ctx, const Work& w, std::uint32_t octant) {
  Work child;
  child.level = w.level + 1;
  child.cube.side = w.cube.side / 2;
  for (int a = 0; a < 3; ++a)
    child.cube.corner[a] = w.cube.corner[a] + (octant >> a & 1) * child.cube.side;
  const std::uint64_t codes_per_child = std::uint64_t(1) << (3 * (ctx.levels - child.level));
  const std::uint64_t base = cube_code(child.cube);
  const auto first = ctx.codes.begin() + std::ptrdiff_t(w.code_lo);
  const auto last = ctx.codes.begin() + std::ptrdiff_t(w.code_hi);
  const auto lo = std::lower_bound(first, last, base);
  const auto hi = std::lower_bound(lo, last, base + codes_per_child);
  if (lo == hi) return std::nullopt;
  child.code_lo = std::size_t(lo - ctx.codes.begin());
  child.code_hi = std::size_t(hi - ctx.codes.begin());
  return child;
}

// Narrows the parent's triangles to those touching `child`, and appends the child's normal (the
// sum of their unit normals) and, when the scene has colours, its mean colour to `block`.
void gather_triangles(const Context& ctx, const Work& parent, Work& child, TempBlock& block) {
  double sum[3] = {0, 0, 0};
  std::array<double, 4> color{0, 0, 0, 0};
  for (const std::uint32_t t : parent.triangles)
    if (touches(ctx.triangles[t], child.cube)) {
      child.triangles.push_back(t);
      sum[0] += ctx.unit_normals[t].x, sum[1] += ctx.unit_normals[t].y;
      sum[2] += ctx.unit_normals[t].z;
      if (!ctx.colors.empty())
        for (int k = 0; k < 4; ++k) color[k] += ctx.colors[t][k];
    }
  block.normals.push_back(format::encode_octahedral(float(sum[0]), float(sum[1]), float(sum[2])));
  if (!ctx.colors.empty()) block.colors.push_back(mean_rgba8(color, child.triangles.size()));
}

struct ContourOutcome {
  bool fitted = false;   // a contour word was appended to the block
  bool covered = false;  // its slab stays within reach of the surface cells: the child is a leaf
};

// Fits `child`'s contour to its triangles clipped to its cube (`pieces` is scratch space); a
// fitted contour is appended to `block` and becomes `child.slab`. Coverage is tested only above
// the finest level, as the finest voxels are leaves anyway.
ContourOutcome fit_child_contour(const Context& ctx, const Work& parent, Work& child,
                                 std::vector<ClipPolygon>& pieces, TempBlock& block) {
  const std::uint32_t side = child.cube.side;
  if (!ctx.contours || side > esvo::kMaxCoveredSide) return {};
  pieces.clear();
  const double box_lo[3] = {double(child.cube.corner[0]), double(child.cube.corner[1]),
                            double(child.cube.corner[2])};
  const double box_hi[3] = {box_lo[0] + side, box_lo[1] + side, box_lo[2] + side};
  for (const std::uint32_t t : child.triangles) {
    const GridTriangle& g = ctx.triangles[t];
    const ClipPolygon p =
        clip_triangle({{g.v[0].x, g.v[0].y, g.v[0].z}}, {{g.v[1].x, g.v[1].y, g.v[1].z}},
                      {{g.v[2].x, g.v[2].y, g.v[2].z}}, box_lo, box_hi);
    if (p.n >= 3) pieces.push_back(p);
  }
  const Slab* parent_slab = parent.slab ? &*parent.slab : nullptr;
  const auto fit = esvo::fit_contour(pieces, child.cube, parent_slab);
  if (!fit) return {};
  block.contours.push_back(fit->word);
  child.slab = fit->slab;
  ContourOutcome outcome{true, false};
  if (child.level != ctx.levels)
    outcome.covered =
        esvo::slab_covered(fit->slab, parent_slab, child.cube,
                           ctx.codes.subspan(child.code_lo, child.code_hi - child.code_lo),
                           cube_code(child.cube), ctx.reach);
  return outcome;
}

void count_node(const TempNode& node, EsvoLevelStats& stats) {
  stats.descriptors += 1;
  stats.voxels += std::popcount(node.valid);
  stats.leaves += std::popcount(std::uint8_t(node.valid & ~node.non_leaf));
  stats.contours += std::popcount(node.contour_mask);
}

// Decides node `index`'s children (valid, leaf, contour, normal) and returns the non-leaf ones.
std::vector<Work> expand(const Context& ctx, TempBlock& block, std::uint32_t index, const Work& w) {
  TempNode node;
  node.level = w.level;
  node.first_contour = std::uint32_t(block.contours.size());
  node.first_normal = std::uint32_t(block.normals.size());
  std::vector<Work> children;
  std::vector<ClipPolygon> pieces;
  for (std::uint32_t octant = 0; octant < 8; ++octant) {
    std::optional<Work> child = child_work(ctx, w, octant);
    if (!child) continue;
    node.valid |= std::uint8_t(1u << octant);
    gather_triangles(ctx, w, *child, block);
    const ContourOutcome contour = fit_child_contour(ctx, w, *child, pieces, block);
    if (contour.fitted) node.contour_mask |= std::uint8_t(1u << octant);
    if (child->level != ctx.levels && !contour.covered) {
      node.non_leaf |= std::uint8_t(1u << octant);
      children.push_back(std::move(*child));
    }
  }
  count_node(node, block.levels[w.level]);
  block.nodes[index] = node;
  return children;
}

// Places `children` as a new group of `block` under node `parent`.
std::uint32_t add_group(TempBlock& block, std::size_t count) {
  const auto first = std::uint32_t(block.nodes.size());
  block.group_starts.push_back(first);
  block.nodes.resize(block.nodes.size() + count);
  return first;
}

void build_subtree(const Context& ctx, TempBlock& block, std::uint32_t index, Work w) {
  std::vector<Work> children = expand(ctx, block, index, w);
  w = {};  // its triangle list is no longer needed below
  if (children.empty()) return;
  const std::uint32_t first = add_group(block, children.size());
  block.nodes[index].first_child = first;
  for (std::size_t i = 0; i < children.size(); ++i)
    build_subtree(ctx, block, first + std::uint32_t(i), std::move(children[i]));
}

// Block 0: the levels above the block level. Children groups at the block level are set aside
// in `pending`, one future block each.
void build_top(const Context& ctx, TempBlock& top, std::uint32_t index, Work w,
               std::vector<std::vector<Work>>& pending) {
  std::vector<Work> children = expand(ctx, top, index, w);
  w = {};
  if (children.empty()) return;
  if (children.front().level == ctx.block_level) {
    top.nodes[index].child_block = true;
    top.nodes[index].first_child = std::uint32_t(pending.size() + 1);  // block 0 is this one
    pending.push_back(std::move(children));
    return;
  }
  const std::uint32_t first = add_group(top, children.size());
  top.nodes[index].first_child = first;
  for (std::size_t i = 0; i < children.size(); ++i)
    build_top(ctx, top, first + std::uint32_t(i), std::move(children[i]), pending);
}

std::uint32_t reach_for(double contour_error) {
  std::uint32_t r = 0;
  while (r < 8 && std::sqrt(2.0 + double(r + 2) * double(r + 2)) <= contour_error) ++r;
  return r;
}

// The build's shared inputs: the surface cells of `voxels` (which must outlive it) and, per
// triangle, its grid-space corners, unit normal and mean colour.
Context make_context(const Scene& scene, const EsvoBuildOptions& options, const Voxels& voxels) {
  Context ctx;
  ctx.scene = &scene;
  ctx.grid = voxels.grid;
  ctx.levels = std::uint32_t(std::bit_width(options.resolution) - 1);
  ctx.block_level = std::min(kMaxBlockLevel, ctx.levels - 1);
  ctx.reach = reach_for(options.contour_error);
  ctx.contours = options.contours;
  ctx.codes = voxels.codes;
  ctx.triangles.reserve(scene.triangles.size());
  ctx.unit_normals.reserve(scene.triangles.size());
  for (const auto& tri : scene.triangles) {
    ctx.triangles.push_back(to_grid(ctx.grid, scene.positions[tri.v[0]], scene.positions[tri.v[1]],
                                    scene.positions[tri.v[2]]));
    const format::Double3 a = to_d(scene.positions[tri.v[0]]), b = to_d(scene.positions[tri.v[1]]),
                          c = to_d(scene.positions[tri.v[2]]);
    const format::Double3 n = cross(b - a, c - a);
    ctx.unit_normals.push_back(n * (1.0 / std::sqrt(dot(n, n))));
    if (scene.colors.empty()) continue;
    std::array<double, 4> mean{0, 0, 0, 0};
    for (const std::uint32_t v : tri.v)
      for (int k = 0; k < 4; ++k) mean[k] += double(scene.colors[v] >> (8 * k) & 0xFF) / 3.0;
    ctx.colors.push_back(mean);
  }
  return ctx;
}

// Block 0 (the top levels), then one block per group of children at the block level, built in
// parallel; each block depends only on its group, so the result is the same for any thread count.
std::vector<TempBlock> build_blocks(const Context& ctx, std::uint32_t resolution,
                                    unsigned threads) {
  Work root;
  root.cube = {{0, 0, 0}, resolution};
  root.code_hi = ctx.codes.size();
  root.triangles.resize(ctx.triangles.size());
  for (std::uint32_t i = 0; i < root.triangles.size(); ++i) root.triangles[i] = i;

  std::vector<TempBlock> blocks(1);
  blocks[0].levels.resize(ctx.levels);
  blocks[0].group_starts.push_back(0);
  blocks[0].nodes.resize(1);
  std::vector<std::vector<Work>> pending;
  if (!ctx.codes.empty()) build_top(ctx, blocks[0], 0, std::move(root), pending);
  blocks.resize(1 + pending.size());
  parallel_for(pending.size(), threads, [&](std::size_t p) {
    TempBlock& block = blocks[p + 1];
    block.levels.resize(ctx.levels);
    std::vector<Work>& group = pending[p];
    const std::uint32_t first = add_group(block, group.size());
    for (std::size_t i = 0; i < group.size(); ++i)
      build_subtree(ctx, block, first + std::uint32_t(i), std::move(group[i]));
    std::vector<Work>().swap(group);
  });
  return blocks;
}

}  // namespace

double esvo_error_bound(const EsvoBuildOptions& options) {
  if (!(std::isfinite(options.contour_error) && options.contour_error >= std::sqrt(3.0))) {
    // Ten digits, so a value just below sqrt(3) does not print as equal to it.
    std::ostringstream message;
    message << std::setprecision(10) << "--contour-error " << options.contour_error
            << " must be finite and at least sqrt(3) = " << std::sqrt(3.0)
            << " voxels (what a finest voxel guarantees)";
    throw std::invalid_argument(message.str());
  }
  if (!options.contours) return std::sqrt(3.0);
  const double r = reach_for(options.contour_error);
  return std::sqrt(2.0 + (r + 1) * (r + 1));
}

FlatEsvo build_esvo(const Scene& scene, const EsvoBuildOptions& options) {
  esvo_error_bound(options);  // validates contour_error
  VoxelizeOptions voxel_options;
  voxel_options.resolution = options.resolution;
  voxel_options.threads = options.threads;
  const Voxels voxels = voxelize_surface(scene, voxel_options);  // validates the resolution
  const Context ctx = make_context(scene, options, voxels);
  std::vector<TempBlock> blocks = build_blocks(ctx, options.resolution, options.threads);
  FlatEsvo out;
  out.grid = ctx.grid;
  out.levels = ctx.levels;
  esvo::flatten_blocks(blocks, out);
  return out;
}

}  // namespace kiln
