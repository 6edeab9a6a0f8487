// Octree construction: each cell with more than leaf_size triangles is split at its centre into
// eight (format::octree_child_cell, the very boxes the traversal computes), and each triangle
// goes to every child its surface meets, by the exact separating-axis test (Akenine-Moller 2001;
// triangle_overlaps_box).
//
// The tree is built one level at a time: every cell of a level is split on its own (in
// parallel; each writes only its own slot), then the level is written out in cell order and its
// children, in octant order, become the next level. That is breadth-first order, the layout's,
// so nothing is re-ordered afterwards and the blob never depends on the thread count; and the
// references of a whole level are known before it is committed, which is what the budget needs.
//
// A cell stays a leaf when
// - it has at most leaf_size triangles;
// - it is at the depth limit, or its centre no longer rounds strictly inside it;
// - splitting makes no progress: some child would still hold all n of its triangles while the
//   children together would hold more than 2n references. That is the signature of many
//   triangles meeting at one point (a vertex of high valence, or one on the cell's centre,
//   which lies in all eight children): splitting further only copies them. A cluster lying
//   inside one octant (a teapot in a stadium) is not copied and keeps descending;
// - the next level would take the references past the budget (reference_budget x triangles,
//   counting the leaves already written): then every cell of the level stays a leaf. Large,
//   mutually crossing triangles otherwise double their references at every level.
#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <span>
#include <stdexcept>

#include "kiln/compiler/octree_builder.hpp"
#include "kiln/runtime/parallel.hpp"
#include "kiln/runtime/triangle_geometry.hpp"

namespace kiln {

namespace {

enum class Outcome : std::uint8_t { kSmall, kDepth, kStalled, kBudget, kSplit };

struct Cell {
  format::Box3f box;
  std::vector<std::uint32_t> prims;  // ascending
};

// What splitting one cell gave: its outcome, and for kSplit its children's triangle lists.
struct Split {
  Outcome outcome = Outcome::kSmall;
  std::vector<std::uint32_t> lists[8];
  std::size_t references = 0;  // in the children
};

struct Context {
  const std::vector<format::RayTriangle>& triangles;
  const OctreeBuildOptions& options;
};

// Triangle lists at least this long are classified on every worker.
constexpr std::size_t kParallelTriangles = 1 << 15;

bool overlaps(const format::Box3f& a, const format::Box3f& b) {
  return a.min.x <= b.max.x && a.max.x >= b.min.x && a.min.y <= b.max.y && a.max.y >= b.min.y &&
         a.min.z <= b.max.z && a.max.z >= b.min.z;
}

// The children (bit per octant) whose cells triangle `t` meets. Its bounding box rules out the
// others; a box overlapping one child only needs no test. Should rounding reject every child
// of a triangle that met the parent, the box's children keep it, so nothing is ever lost.
std::uint32_t child_mask_of(const format::RayTriangle& t, const format::Box3f children[8]) {
  format::Box3f box;
  box.grow(t.v0), box.grow(t.v1), box.grow(t.v2);
  std::uint32_t by_box = 0;
  for (std::uint32_t c = 0; c < 8; ++c) by_box |= overlaps(box, children[c]) ? 1u << c : 0u;
  if (std::popcount(by_box) <= 1) return by_box;
  std::uint32_t mask = 0;
  for (std::uint32_t c = 0; c < 8; ++c)
    if (by_box >> c & 1u)
      mask |= triangle_overlaps_box(to_d(t.v0), to_d(t.v1), to_d(t.v2), to_d(children[c].min),
                                    to_d(children[c].max))
                  ? 1u << c
                  : 0u;
  return mask != 0 ? mask : by_box;
}

bool splittable(const format::Box3f& cell) {
  for (int a = 0; a < 3; ++a) {
    const float lo = format::at(cell.min, a), hi = format::at(cell.max, a);
    const float mid = format::octree_mid(lo, hi);
    if (!(mid > lo && mid < hi)) return false;
  }
  return true;
}

Split split_cell(const Context& ctx, const Cell& cell, std::uint32_t depth, unsigned threads) {
  Split out;
  const std::size_t n = cell.prims.size();
  if (n <= ctx.options.leaf_size) return out;
  if (depth >= ctx.options.max_depth || !splittable(cell.box)) {
    out.outcome = Outcome::kDepth;
    return out;
  }
  format::Box3f children[8];
  for (std::uint32_t c = 0; c < 8; ++c) children[c] = format::octree_child_cell(cell.box, c);
  std::vector<std::uint8_t> masks(n);
  parallel_for_batched(n, 4096, n >= kParallelTriangles ? threads : 1, [&](std::size_t i) {
    masks[i] = std::uint8_t(child_mask_of(ctx.triangles[cell.prims[i]], children));
  });
  std::size_t largest = 0;
  for (std::uint32_t c = 0; c < 8; ++c) {
    for (std::size_t i = 0; i < n; ++i)
      if (masks[i] >> c & 1u) out.lists[c].push_back(cell.prims[i]);
    out.references += out.lists[c].size();
    largest = std::max(largest, out.lists[c].size());
  }
  if (largest == n && 2 * out.references > 3 * n) {
    out = Split{};
    out.outcome = Outcome::kStalled;
    return out;
  }
  out.outcome = Outcome::kSplit;
  return out;
}

void write_leaf(const Cell& cell, Outcome outcome, FlatOctree& tree) {
  if (cell.prims.size() > format::kOctreeMaxLeafReferences ||
      tree.prim_ids.size() + cell.prims.size() > std::numeric_limits<std::uint32_t>::max())
    throw std::runtime_error("octree: more references than the layout can address");
  tree.nodes.push_back(format::OctreeNode::leaf(std::uint32_t(tree.prim_ids.size()),
                                                std::uint32_t(cell.prims.size())));
  tree.prim_ids.insert(tree.prim_ids.end(), cell.prims.begin(), cell.prims.end());
  OctreeStatistics& s = tree.stats;
  s.leaf_count += 1;
  s.largest_leaf = std::max(s.largest_leaf, std::uint32_t(cell.prims.size()));
  s.depth_limited_leaves += outcome == Outcome::kDepth || outcome == Outcome::kBudget;
  s.stalled_leaves += outcome == Outcome::kStalled;
}

// Splits every cell of `level` (depth `depth`), writes the level's nodes to `tree` and returns
// the next level.
std::vector<Cell> build_level(const Context& ctx, std::vector<Cell>& level, std::uint32_t depth,
                              FlatOctree& tree) {
  const unsigned threads = ctx.options.threads;
  std::vector<Split> splits(level.size());
  // One cell (the root): its triangles are classified in parallel instead.
  parallel_for(level.size(), level.size() == 1 ? 1 : threads, [&](std::size_t i) {
    splits[i] = split_cell(ctx, level[i], depth, level.size() == 1 ? threads : 1);
  });
  // Written leaves, this level's leaves, and the next level: what the tree holds if it splits.
  std::uint64_t next_references = 0, references = tree.prim_ids.size();
  for (std::size_t i = 0; i < level.size(); ++i)
    (splits[i].outcome == Outcome::kSplit ? next_references : references) +=
        splits[i].outcome == Outcome::kSplit ? splits[i].references : level[i].prims.size();
  const double budget = double(ctx.options.reference_budget) * double(ctx.triangles.size());
  if (double(references) + double(next_references) > budget) {
    tree.stats.budget_reached = next_references > 0;
    for (Split& s : splits)
      if (s.outcome == Outcome::kSplit) s = Split{}, s.outcome = Outcome::kBudget;
  }
  tree.stats.max_depth = depth;
  std::vector<Cell> next;
  std::uint64_t next_index = tree.nodes.size() + level.size();
  for (std::size_t i = 0; i < level.size(); ++i) {
    Split& s = splits[i];
    if (s.outcome != Outcome::kSplit) {
      write_leaf(level[i], s.outcome, tree);
      continue;
    }
    std::uint32_t mask = 0;
    for (std::uint32_t c = 0; c < 8; ++c) {
      if (s.lists[c].empty()) continue;
      mask |= 1u << c;
      next.push_back({format::octree_child_cell(level[i].box, c), std::move(s.lists[c])});
    }
    if (next_index + std::popcount(mask) > std::numeric_limits<std::uint32_t>::max())
      throw std::runtime_error("octree: more nodes than the layout can address");
    tree.nodes.push_back(format::OctreeNode::interior(mask, std::uint32_t(next_index)));
    tree.stats.empty_cell_count += 8 - std::popcount(mask);
    next_index += std::popcount(mask);
  }
  return next;
}

}  // namespace

format::Box3f octree_root_cell(const format::Box3f& scene_bounds) {
  float extent = 0;
  for (int a = 0; a < 3; ++a)
    extent = std::max(extent, format::at(scene_bounds.max, a) - format::at(scene_bounds.min, a));
  if (!(extent > 0) || !std::isfinite(extent)) extent = 1;
  format::Box3f cell;
  for (int a = 0; a < 3; ++a) {
    const float lo = format::at(scene_bounds.min, a);
    float hi = lo + extent;
    while (!(hi > lo) || hi < format::at(scene_bounds.max, a))
      hi = std::nextafter(hi, std::numeric_limits<float>::infinity());
    format::at(cell.min, a) = lo;
    format::at(cell.max, a) = hi;
  }
  return cell;
}

FlatOctree build_octree(const Scene& scene, const OctreeBuildOptions& options) {
  if (scene.triangles.empty()) throw std::runtime_error("octree: the scene has no triangles");
  if (options.max_depth > format::kOctreeMaxDepth || options.leaf_size == 0 ||
      options.reference_budget == 0)
    throw std::runtime_error("octree: leaf size, depth limit or reference budget out of range");
  FlatOctree tree;
  tree.bounds = octree_root_cell(scene.bounds);
  tree.triangles.reserve(scene.triangles.size());
  for (const format::Triangle& t : scene.triangles) {
    const auto& v = scene.positions;
    tree.triangles.push_back({v[t.v[0]], v[t.v[1]], v[t.v[2]]});
  }
  std::vector<Cell> level(1);
  level[0].box = tree.bounds;
  level[0].prims.resize(scene.triangles.size());
  for (std::uint32_t i = 0; i < level[0].prims.size(); ++i) level[0].prims[i] = i;
  const Context ctx{tree.triangles, options};
  for (std::uint32_t depth = 0; !level.empty(); ++depth)
    level = build_level(ctx, level, depth, tree);

  OctreeStatistics& s = tree.stats;
  s.node_count = tree.nodes.size();
  s.reference_count = tree.prim_ids.size();
  const double n = double(scene.triangles.size());
  s.references_per_triangle = double(s.reference_count) / n;
  s.bytes_per_triangle = double(tree.nodes.size() * sizeof(format::OctreeNode) +
                                tree.prim_ids.size() * sizeof(std::uint32_t) +
                                tree.triangles.size() * sizeof(format::RayTriangle)) /
                         n;
  return tree;
}

}  // namespace kiln
