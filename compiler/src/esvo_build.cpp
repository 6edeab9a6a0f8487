// Top-down ESVO construction. The surface cells come from the voxelizer (the same conservative
// cells every voxel structure holds), so a voxel exists exactly where a surface cell lies below it;
// the triangles are narrowed to each child by the voxelizer's separating-axis test, clipped to it,
// and fitted with a contour. A voxel stops subdividing when its contour slab stays within reach
// of the surface cells (esvo_contour.hpp), or at the finest level.
//
// The top levels form block 0; every group of children at the block level starts its own block,
// built as an independent task, so the result never depends on the thread count.
//
// Memory follows the ESVO, not the surface: the grid is cut into cubes at a load level chosen
// from the memory budget. Each cube is voxelized on its own (only the triangles that can reach
// it), its subtree built as a fragment and its surface cells freed, in parallel; the levels above
// then need only which cubes hold surface, and take each fragment in where the whole-grid build
// would have built it, so the output is byte-identical to voxelizing the whole grid at once.
#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>

#include "esvo_contour.hpp"
#include "esvo_tree.hpp"
#include "kiln/formats/voxel_grid.hpp"
#include "kiln/runtime/parallel.hpp"
#include "voxel_options.hpp"

namespace kiln {

namespace {

using esvo::Cube;
using esvo::Slab;
using esvo::TempBlock;
using esvo::TempNode;

constexpr std::uint32_t kMaxBlockLevel = 4;  // up to 8^3 blocks: enough tasks to balance

// Cubes are never narrower than this, so the levels above the load level never test coverage
// (which needs the surface cells): their voxels are wider than esvo::kMaxCoveredSide.
constexpr std::uint32_t kMinCubeSide = esvo::kMaxCoveredSide;

// A triangle's candidate voxels, widened by one voxel each way: a superset of the voxels the
// voxelizer may set for it, so a cube no range meets holds no surface.
struct CellRange {
  std::int64_t lo[3], hi[3];
};

struct Fragment;

struct Context {
  const Scene* scene = nullptr;
  VoxelGrid grid;
  std::uint32_t levels = 0, block_level = 0, reach = 0;
  std::uint32_t load_level = 0;  // cubes voxelized one at a time; 0: the whole grid at once
  bool contours = true;
  std::vector<GridTriangle> triangles;        // in grid units
  std::vector<format::Double3> unit_normals;  // as the voxelizer sums them
  std::vector<std::array<double, 4>> colors;  // per triangle: its corners' mean RGBA, 0..255
  std::vector<CellRange> ranges;              // per triangle, when load_level > 0
  // While the levels above the load level are built: the fragments of the cubes holding surface
  // and their corners' Morton codes (ascending), which stand in for the surface cells there.
  bool splicing = false;
  std::span<Fragment> fragments;
  std::span<const std::uint64_t> fragment_codes;
};

// A voxel whose children are still to be decided.
struct Work {
  Cube cube;
  std::uint32_t level = 0;
  std::vector<std::uint32_t> triangles;  // those touching the cube, ascending
  std::span<const std::uint64_t> codes;  // its surface cells (or, above the load level, cubes)
  std::optional<Slab> slab;              // its own contour, if any
};

// A cube at the load level, built on its own: its node (node 0 of `part`, which its parent's
// block takes in) and its subtree, in `part` below the block level, else in `part` and `blocks`.
struct Fragment {
  bool covered = false;  // its contour covers its surface cells: a leaf, nothing below
  TempBlock part;
  std::vector<TempBlock> blocks;
};

std::uint64_t cube_code(const Cube& c) {
  return format::morton_code(c.corner[0], c.corner[1], c.corner[2]);
}

Cube child_cube(const Cube& c, std::uint32_t octant) {
  Cube child;
  child.side = c.side / 2;
  for (int a = 0; a < 3; ++a) child.corner[a] = c.corner[a] + (octant >> a & 1) * child.side;
  return child;
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

// The parent's triangles that touch `cube`, in the parent's order.
std::vector<std::uint32_t> narrow(const Context& ctx, std::span<const std::uint32_t> parent,
                                  const Cube& cube) {
  std::vector<std::uint32_t> out;
  for (const std::uint32_t t : parent)
    if (touches(ctx.triangles[t], cube)) out.push_back(t);
  return out;
}

// Child `octant` of `w` with its surface cells, or nothing when it holds none.
std::optional<Work> child_work(const Context& ctx, const Work& w, std::uint32_t octant) {
  Work child;
  child.level = w.level + 1;
  child.cube = child_cube(w.cube, octant);
  const std::uint64_t codes_per_child = std::uint64_t(1) << (3 * (ctx.levels - child.level));
  const std::uint64_t base = cube_code(child.cube);
  const auto lo = std::lower_bound(w.codes.begin(), w.codes.end(), base);
  const auto hi = std::lower_bound(lo, w.codes.end(), base + codes_per_child);
  if (lo == hi) return std::nullopt;
  child.codes = w.codes.subspan(std::size_t(lo - w.codes.begin()), std::size_t(hi - lo));
  return child;
}

// Narrows the parent's triangles to those touching `child`, and appends the child's normal (the
// sum of their unit normals) and, when the scene has colours, its mean colour to `block`.
void gather_triangles(const Context& ctx, const Work& parent, Work& child, TempBlock& block) {
  child.triangles = narrow(ctx, parent.triangles, child.cube);
  double sum[3] = {0, 0, 0};
  std::array<double, 4> color{0, 0, 0, 0};
  for (const std::uint32_t t : child.triangles) {
    sum[0] += ctx.unit_normals[t].x, sum[1] += ctx.unit_normals[t].y;
    sum[2] += ctx.unit_normals[t].z;
    if (!ctx.colors.empty())
      for (int k = 0; k < 4; ++k) color[k] += ctx.colors[t][k];
  }
  block.normals.push_back(format::encode_octahedral(float(sum[0]), float(sum[1]), float(sum[2])));
  if (!ctx.colors.empty()) block.colors.push_back(mean_rgba8(color, child.triangles.size()));
}

// Fits `child`'s contour to its triangles clipped to its cube (`pieces` is scratch space); a
// fitted contour is appended to `block`, becomes `child.slab`, and true is returned.
bool fit_child_contour(const Context& ctx, const Work& parent, Work& child,
                       std::vector<ClipPolygon>& pieces, TempBlock& block) {
  const std::uint32_t side = child.cube.side;
  if (!ctx.contours || side > esvo::kMaxCoveredSide) return false;
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
  const auto fit = esvo::fit_contour(pieces, child.cube, parent.slab ? &*parent.slab : nullptr);
  if (!fit) return false;
  block.contours.push_back(fit->word);
  child.slab = fit->slab;
  return true;
}

Fragment& fragment_of(const Context& ctx, const Work& w) {
  return ctx.fragments[std::size_t(w.codes.data() - ctx.fragment_codes.data())];
}

// Whether a contoured `child` covers its surface cells (then it is a leaf). Coverage is tested
// only above the finest level, as the finest voxels are leaves anyway; a cube at the load level
// was tested when it was built.
bool child_covered(const Context& ctx, const Work& parent, const Work& child) {
  if (!child.slab || child.level == ctx.levels) return false;
  if (ctx.splicing && child.level == ctx.load_level) return fragment_of(ctx, child).covered;
  return esvo::slab_covered(*child.slab, parent.slab ? &*parent.slab : nullptr, child.cube,
                            child.codes, cube_code(child.cube), ctx.reach);
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
    if (fit_child_contour(ctx, w, *child, pieces, block))
      node.contour_mask |= std::uint8_t(1u << octant);
    if (child->level != ctx.levels && !child_covered(ctx, w, *child)) {
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

// Takes `part` (built on its own, its root at node 0) into `block` at node `index`, exactly as if
// it had been built there now: its other nodes, groups, contours and attachments follow what
// `block` holds, and its child blocks are numbered after the `blocks_before` already set aside.
void splice(TempBlock& block, std::uint32_t index, const TempBlock& part,
            std::size_t blocks_before) {
  const auto base = std::uint32_t(block.nodes.size() - 1);  // part's node i goes to base + i
  const auto contours = std::uint32_t(block.contours.size());
  const auto normals = std::uint32_t(block.normals.size());
  auto moved = [&](TempNode n) {
    if (n.child_block)
      n.first_child += std::uint32_t(blocks_before);
    else if (n.first_child != esvo::kNoGroup)
      n.first_child += base;
    n.first_contour += contours, n.first_normal += normals;
    return n;
  };
  block.nodes[index] = moved(part.nodes[0]);
  for (std::size_t i = 1; i < part.nodes.size(); ++i) block.nodes.push_back(moved(part.nodes[i]));
  for (const std::uint32_t g : part.group_starts) block.group_starts.push_back(base + g);
  block.contours.insert(block.contours.end(), part.contours.begin(), part.contours.end());
  block.normals.insert(block.normals.end(), part.normals.begin(), part.normals.end());
  block.colors.insert(block.colors.end(), part.colors.begin(), part.colors.end());
  for (std::size_t l = 0; l < part.levels.size(); ++l) {
    EsvoLevelStats& s = block.levels[l];
    s.descriptors += part.levels[l].descriptors, s.voxels += part.levels[l].voxels;
    s.leaves += part.levels[l].leaves, s.contours += part.levels[l].contours;
  }
  block.far_pointers += part.far_pointers;
}

// The blocks below block 0, in order: groups still to build (one task each), or blocks that
// fragments built already. One build never has both.
struct Pending {
  std::vector<std::vector<Work>> groups;
  std::vector<TempBlock> built;
  std::size_t count() const { return groups.size() + built.size(); }
};

void build_subtree(const Context& ctx, TempBlock& block, std::uint32_t index, Work w) {
  if (ctx.splicing && w.level == ctx.load_level) {
    Fragment& f = fragment_of(ctx, w);
    splice(block, index, f.part, 0);
    f = {};
    return;
  }
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
void build_top(const Context& ctx, TempBlock& top, std::uint32_t index, Work w, Pending& pending) {
  if (ctx.splicing && w.level == ctx.load_level) {
    Fragment& f = fragment_of(ctx, w);
    splice(top, index, f.part, pending.count());
    for (TempBlock& b : f.blocks) pending.built.push_back(std::move(b));
    f = {};
    return;
  }
  std::vector<Work> children = expand(ctx, top, index, w);
  w = {};
  if (children.empty()) return;
  if (children.front().level == ctx.block_level) {
    top.nodes[index].child_block = true;
    top.nodes[index].first_child = std::uint32_t(pending.count() + 1);  // block 0 is this one
    pending.groups.push_back(std::move(children));
    return;
  }
  const std::uint32_t first = add_group(top, children.size());
  top.nodes[index].first_child = first;
  for (std::size_t i = 0; i < children.size(); ++i)
    build_top(ctx, top, first + std::uint32_t(i), std::move(children[i]), pending);
}

// One block per group, in parallel; each depends only on its group.
std::vector<TempBlock> build_groups(const Context& ctx, std::vector<std::vector<Work>>& groups,
                                    unsigned threads) {
  std::vector<TempBlock> blocks(groups.size());
  parallel_for(groups.size(), threads, [&](std::size_t p) {
    TempBlock& block = blocks[p];
    block.levels.resize(ctx.levels);
    std::vector<Work>& group = groups[p];
    const std::uint32_t first = add_group(block, group.size());
    for (std::size_t i = 0; i < group.size(); ++i)
      build_subtree(ctx, block, first + std::uint32_t(i), std::move(group[i]));
    std::vector<Work>().swap(group);
  });
  return blocks;
}

std::uint32_t reach_for(double contour_error) {
  std::uint32_t r = 0;
  while (r < 8 && std::sqrt(2.0 + double(r + 2) * double(r + 2)) <= contour_error) ++r;
  return r;
}

CellRange cell_range(const GridTriangle& t, std::uint32_t resolution) {
  CellRange r;
  const double limit = double(resolution) + 4;
  for (int a = 0; a < 3; ++a) {
    const double x0 = format::at(t.v[0], a), x1 = format::at(t.v[1], a), x2 = format::at(t.v[2], a);
    // Clamped before the conversion; NaN corners reach nothing.
    const double lo = std::clamp(std::min({x0, x1, x2}), -4.0, limit);
    const double hi = std::clamp(std::max({x0, x1, x2}), -4.0, limit);
    r.lo[a] = std::isnan(lo) ? 1 : std::int64_t(std::ceil(lo)) - 2;
    r.hi[a] = std::isnan(hi) ? 0 : std::int64_t(std::floor(hi)) + 1;
  }
  return r;
}

bool reaches(const CellRange& r, const Cube& c) {
  for (int a = 0; a < 3; ++a)
    if (r.hi[a] < std::int64_t(c.corner[a]) || r.lo[a] >= std::int64_t(c.corner[a]) + c.side)
      return false;
  return true;
}

// A cube at the load level that may hold surface: its work as its parent would make it (cube,
// triangles, contour) and the triangles whose candidate voxels can reach it.
struct Candidate {
  Work work;
  std::vector<std::uint32_t> reaching;
};

// Walks the levels above the load level down every octant some triangle can reach.
void plan_cubes(const Context& ctx, const Work& w, std::span<const std::uint32_t> reaching,
                std::vector<Candidate>& out) {
  std::vector<ClipPolygon> pieces;
  for (std::uint32_t octant = 0; octant < 8; ++octant) {
    Candidate c;
    c.work.level = w.level + 1;
    c.work.cube = child_cube(w.cube, octant);
    for (const std::uint32_t t : reaching)
      if (reaches(ctx.ranges[t], c.work.cube)) c.reaching.push_back(t);
    if (c.reaching.empty()) continue;
    c.work.triangles = narrow(ctx, w.triangles, c.work.cube);
    if (c.work.level < ctx.load_level) {
      plan_cubes(ctx, c.work, c.reaching, out);
      continue;
    }
    TempBlock scratch;  // the contour word goes to the parent's block when the cube is taken in
    fit_child_contour(ctx, w, c.work, pieces, scratch);
    out.push_back(std::move(c));
  }
}

// Voxelizes candidate `c`'s cube and builds its fragment; its surface cells are freed on return.
// Returns false when the cube holds no surface.
bool build_fragment(const Context& ctx, Candidate& c, Fragment& f) {
  const Cube& cube = c.work.cube;
  const VoxelCube voxel_cube{{cube.corner[0], cube.corner[1], cube.corner[2]}, cube.side};
  const std::vector<std::uint64_t> codes =
      voxelize_surface_cube(*ctx.scene, ctx.grid, voxel_cube, c.reaching, false, 1).codes;
  std::vector<std::uint32_t>().swap(c.reaching);
  if (codes.empty()) return false;
  Work w = std::move(c.work);
  w.codes = codes;
  // Its parent is wider than kMaxCoveredSide, so it has no contour of its own.
  Work parent;
  f.covered = child_covered(ctx, parent, w);
  if (f.covered || w.level == ctx.levels) return true;
  f.part.levels.resize(ctx.levels);
  f.part.nodes.resize(1);
  if (w.level < ctx.block_level) {
    Pending pending;
    build_top(ctx, f.part, 0, std::move(w), pending);
    f.blocks = build_groups(ctx, pending.groups, 1);
  } else {
    build_subtree(ctx, f.part, 0, std::move(w));
  }
  return true;
}

// The build's shared inputs: per triangle, its grid-space corners, unit normal and mean colour.
Context make_context(const Scene& scene, const EsvoBuildOptions& options) {
  Context ctx;
  ctx.scene = &scene;
  ctx.grid = fit_voxel_grid(scene.bounds, options.resolution);
  ctx.levels = std::uint32_t(std::bit_width(options.resolution) - 1);
  ctx.block_level = std::min(kMaxBlockLevel, ctx.levels - 1);
  ctx.reach = reach_for(options.contour_error);
  ctx.contours = options.contours;
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

Work root_work(const Context& ctx, std::uint32_t resolution) {
  Work root;
  root.cube = {{0, 0, 0}, resolution};
  root.triangles.resize(ctx.triangles.size());
  for (std::uint32_t i = 0; i < root.triangles.size(); ++i) root.triangles[i] = i;
  return root;
}

// Block 0 from `root`, then the blocks below it (built now, or already by fragments).
std::vector<TempBlock> build_from_root(const Context& ctx, Work root, unsigned threads) {
  std::vector<TempBlock> blocks(1);
  blocks[0].levels.resize(ctx.levels);
  blocks[0].group_starts.push_back(0);
  blocks[0].nodes.resize(1);
  Pending pending;
  if (!root.codes.empty()) build_top(ctx, blocks[0], 0, std::move(root), pending);
  std::vector<TempBlock> below = build_groups(ctx, pending.groups, threads);
  if (below.empty()) below = std::move(pending.built);
  for (TempBlock& b : below) blocks.push_back(std::move(b));
  return blocks;
}

// The whole grid's surface cells at once (load level 0).
std::vector<TempBlock> build_in_core(const Context& ctx, std::uint32_t resolution,
                                     unsigned threads) {
  VoxelizeOptions voxel_options;
  voxel_options.resolution = resolution;
  voxel_options.threads = threads;
  const Voxels voxels = voxelize_surface(*ctx.scene, voxel_options);
  Work root = root_work(ctx, resolution);
  root.codes = voxels.codes;
  return build_from_root(ctx, std::move(root), threads);
}

// Cube by cube: the fragments in parallel (each cube's surface cells alive only while its task
// runs), then the levels above them, taking each fragment in.
std::vector<TempBlock> build_by_cubes(Context& ctx, std::uint32_t resolution, unsigned threads,
                                      bool progress) {
  ctx.ranges.reserve(ctx.triangles.size());
  for (const GridTriangle& t : ctx.triangles) ctx.ranges.push_back(cell_range(t, resolution));
  Work root = root_work(ctx, resolution);
  std::vector<Candidate> candidates;
  plan_cubes(ctx, root, root.triangles, candidates);
  std::vector<Fragment> fragments(candidates.size());
  std::vector<char> holds(candidates.size(), 0);
  std::vector<std::uint64_t> codes(candidates.size());
  std::atomic<std::size_t> done{0};
  parallel_for(candidates.size(), threads, [&](std::size_t i) {
    codes[i] = cube_code(candidates[i].work.cube);
    holds[i] = build_fragment(ctx, candidates[i], fragments[i]);
    candidates[i] = {};
    const std::size_t n = ++done;
    if (progress && n * 100 / candidates.size() != (n - 1) * 100 / candidates.size())
      std::fprintf(stderr, "\resvo: %zu/%zu cubes of %u^3", n, candidates.size(),
                   candidates.size() == 0 ? 0 : resolution >> ctx.load_level);
  });
  if (progress && !candidates.empty()) std::fputc('\n', stderr);
  std::size_t kept = 0;
  for (std::size_t i = 0; i < candidates.size(); ++i)
    if (holds[i]) {
      if (kept != i) fragments[kept] = std::move(fragments[i]);  // never a self-move
      codes[kept++] = codes[i];
    }
  fragments.resize(kept);
  codes.resize(kept);
  ctx.splicing = true;
  ctx.fragments = fragments;
  ctx.fragment_codes = codes;
  root.codes = codes;
  std::vector<TempBlock> blocks = build_from_root(ctx, std::move(root), threads);
  ctx.splicing = false;
  return blocks;
}

// The side of the cubes voxelized one at a time: the largest whose surface cells (with the
// voxelizer's working copy, 16 B each, for surfaces as dense as kCellsPerFace cells per square
// of the side) fit a quarter of the budget on every thread at once.
std::uint32_t cube_side_for(const EsvoBuildOptions& options) {
  if (options.cube_side != 0) return std::min(options.cube_side, options.resolution);
  constexpr std::uint64_t kBytesPerCell = 16, kCellsPerFace = 8;
  const std::uint64_t threads = std::max(1u, resolve_thread_count(options.threads));
  const std::uint64_t budget =
      options.memory_budget != 0 ? options.memory_budget : default_memory_budget();
  std::uint64_t side = options.resolution;
  while (side > kMinCubeSide && threads * kBytesPerCell * kCellsPerFace * side * side > budget / 4)
    side /= 2;
  return std::uint32_t(side);
}

std::uint32_t load_level_for(const EsvoBuildOptions& options, std::uint32_t levels) {
  const std::uint32_t side = cube_side_for(options);
  if (side >= options.resolution || options.resolution <= kMinCubeSide) return 0;
  return levels - std::uint32_t(std::bit_width(std::max(side, kMinCubeSide)) - 1);
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
  if (!format::is_valid_voxel_resolution(options.resolution))
    throw std::invalid_argument("--resolution " + std::to_string(options.resolution) +
                                " must be a power of two in " +
                                std::to_string(format::kVoxelMinResolution) + ".." +
                                std::to_string(format::kVoxelMaxResolution));
  Context ctx = make_context(scene, options);
  ctx.load_level = load_level_for(options, ctx.levels);
  std::vector<TempBlock> blocks =
      ctx.load_level == 0
          ? build_in_core(ctx, options.resolution, options.threads)
          : build_by_cubes(ctx, options.resolution, options.threads, options.progress);
  FlatEsvo out;
  out.grid = ctx.grid;
  out.levels = ctx.levels;
  esvo::flatten_blocks(blocks, out);
  return out;
}

}  // namespace kiln
