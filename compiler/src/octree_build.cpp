// Octree construction: each cell with more than leaf_size triangles is split at its centre into
// eight (format::octree_child_cell, the very boxes the traversal computes), and each triangle
// goes to every child its surface meets, by the exact separating-axis test (Akenine-Moller 2001;
// triangle_overlaps_box). A temporary tree is built first (the root's eight subtrees in
// parallel: each is a pure function of its cell and triangle list), then flattened breadth first
// in octant order, so the blob never depends on the thread count.
//
// A cell stays a leaf when it has at most leaf_size triangles, at the depth limit, when its
// centre no longer rounds strictly inside it (floats exhausted), or when splitting makes no
// progress: some child would still hold all n of its triangles while the children together
// would hold more than 2n references. That is the signature of many triangles meeting at one
// point or crossing one small region (a fan around a vertex of high valence, or a vertex on the
// cell's centre, which lies in all eight children): splitting further only copies them. A
// cluster that merely lies inside one octant (a teapot in a stadium) is not duplicated and keeps
// descending.
#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <memory>
#include <span>
#include <stdexcept>

#include "kiln/compiler/octree_builder.hpp"
#include "kiln/runtime/parallel.hpp"
#include "kiln/runtime/triangle_geometry.hpp"

namespace kiln {

namespace {

enum class LeafReason : std::uint8_t { kSmall, kDepth, kStalled };

struct TempNode {
  std::uint32_t mask = 0;            // present children
  std::vector<TempNode> children;    // present children in octant order
  std::vector<std::uint32_t> prims;  // a leaf's triangles, ascending
  LeafReason reason = LeafReason::kSmall;
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

TempNode build_node(const Context& ctx, const format::Box3f& cell, std::vector<std::uint32_t> prims,
                    std::uint32_t depth);

// Splits `node`'s triangles among its eight children; false (node left a leaf) without progress.
bool split(const Context& ctx, const format::Box3f& cell, std::uint32_t depth, TempNode& node) {
  format::Box3f children[8];
  for (std::uint32_t c = 0; c < 8; ++c) children[c] = format::octree_child_cell(cell, c);
  const std::vector<std::uint32_t>& prims = node.prims;
  std::vector<std::uint8_t> masks(prims.size());
  const unsigned threads =
      depth == 0 && prims.size() >= kParallelTriangles ? ctx.options.threads : 1;
  parallel_for_batched(prims.size(), 4096, threads, [&](std::size_t i) {
    masks[i] = std::uint8_t(child_mask_of(ctx.triangles[prims[i]], children));
  });
  std::vector<std::uint32_t> lists[8];
  std::size_t total = 0, largest = 0;
  for (std::uint32_t c = 0; c < 8; ++c) {
    for (std::size_t i = 0; i < prims.size(); ++i)
      if (masks[i] >> c & 1u) lists[c].push_back(prims[i]);
    total += lists[c].size();
    largest = std::max(largest, lists[c].size());
  }
  const std::size_t n = prims.size();
  if (largest == n && total > 2 * n) return false;
  node.prims = {};
  std::uint32_t octants[8];
  for (std::uint32_t c = 0; c < 8; ++c)
    if (!lists[c].empty()) octants[node.children.size()] = c, node.children.emplace_back();
  for (const std::uint32_t c : std::span(octants, node.children.size())) node.mask |= 1u << c;
  parallel_for(node.children.size(), depth == 0 ? ctx.options.threads : 1, [&](std::size_t i) {
    const std::uint32_t c = octants[i];
    node.children[i] = build_node(ctx, children[c], std::move(lists[c]), depth + 1);
  });
  return true;
}

TempNode build_node(const Context& ctx, const format::Box3f& cell, std::vector<std::uint32_t> prims,
                    std::uint32_t depth) {
  TempNode node;
  node.prims = std::move(prims);
  if (node.prims.size() <= ctx.options.leaf_size) return node;
  if (depth >= ctx.options.max_depth || !splittable(cell)) {
    node.reason = LeafReason::kDepth;
    return node;
  }
  if (!split(ctx, cell, depth, node)) node.reason = LeafReason::kStalled;
  return node;
}

// Breadth first, children in octant order: node i's children start at the next free index, and
// leaves take their references in node order.
void flatten(const TempNode& root, FlatOctree& out) {
  std::vector<const TempNode*> order{&root};
  std::vector<std::uint8_t> depth{0};
  OctreeStatistics& s = out.stats;
  for (std::size_t i = 0; i < order.size(); ++i) {
    const TempNode& t = *order[i];
    s.max_depth = std::max<std::uint32_t>(s.max_depth, depth[i]);
    if (t.children.empty()) {
      if (t.prims.size() > format::kOctreeMaxLeafReferences ||
          out.prim_ids.size() + t.prims.size() > std::numeric_limits<std::uint32_t>::max())
        throw std::runtime_error("octree: more references than the layout can address");
      out.nodes.push_back(format::OctreeNode::leaf(std::uint32_t(out.prim_ids.size()),
                                                   std::uint32_t(t.prims.size())));
      out.prim_ids.insert(out.prim_ids.end(), t.prims.begin(), t.prims.end());
      s.leaf_count += 1;
      s.largest_leaf = std::max(s.largest_leaf, std::uint32_t(t.prims.size()));
      s.depth_limited_leaves += t.reason == LeafReason::kDepth;
      s.stalled_leaves += t.reason == LeafReason::kStalled;
      continue;
    }
    if (order.size() + t.children.size() > std::numeric_limits<std::uint32_t>::max())
      throw std::runtime_error("octree: more nodes than the layout can address");
    out.nodes.push_back(format::OctreeNode::interior(t.mask, std::uint32_t(order.size())));
    s.empty_cell_count += 8 - t.children.size();
    for (const TempNode& child : t.children) {
      order.push_back(&child);
      depth.push_back(std::uint8_t(depth[i] + 1));
    }
  }
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
  if (options.max_depth > format::kOctreeMaxDepth || options.leaf_size == 0)
    throw std::runtime_error("octree: leaf size or depth limit out of range");
  FlatOctree tree;
  tree.bounds = octree_root_cell(scene.bounds);
  tree.triangles.reserve(scene.triangles.size());
  for (const format::Triangle& t : scene.triangles) {
    const auto& v = scene.positions;
    tree.triangles.push_back({v[t.v[0]], v[t.v[1]], v[t.v[2]]});
  }
  std::vector<std::uint32_t> all(scene.triangles.size());
  for (std::uint32_t i = 0; i < all.size(); ++i) all[i] = i;
  const Context ctx{tree.triangles, options};
  const TempNode root = build_node(ctx, tree.bounds, std::move(all), 0);
  flatten(root, tree);

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
