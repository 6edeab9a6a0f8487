// SAH k-d tree construction in O(N log N) after Wald & Havran, "On building fast kd-trees for ray
// tracing, and on doing that in O(N log N)" (2006): per-axis event lists are sorted once; a node
// sweeps them to find the best plane, then splits them in order, so only the events of
// triangles straddling the plane (re-clipped to each child: "perfect splits") need sorting.
#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>

#include "kiln/compiler/kdtree_builder.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln {

namespace {

enum EventType : std::uint8_t { kEnd = 0, kPlanar = 1, kStart = 2 };

// Sorted by position, then end < planar < start (the sweep's order), then primitive id so the
// order is total and the tree does not depend on how a sort breaks ties.
struct Event {
  float pos;
  std::uint32_t prim;
  EventType type;
};
bool operator<(const Event& a, const Event& b) {
  if (a.pos != b.pos) return a.pos < b.pos;
  if (a.type != b.type) return a.type < b.type;
  return a.prim < b.prim;
}

using EventLists = std::array<std::vector<Event>, 3>;

enum Side : std::uint8_t { kBoth = 0, kLeftOnly = 1, kRightOnly = 2 };

struct Split {
  int axis = -1;
  float pos = 0;
  bool planar_left = true;
  float cost = INFINITY;
};

// A subtree in pre-order with indices relative to its own arrays.
struct Subtree {
  std::vector<format::KdNode> nodes;
  std::vector<std::uint32_t> prims;
};

// Subtrees with at least this many events, near the root, are built on their own thread; a
// subtree is a pure function of its cell and events, so the tree does not depend on who builds it.
constexpr std::size_t kParallelEvents = 1 << 15;

struct Context {
  const Scene& scene;
  const KdTreeBuildOptions& options;
  std::uint32_t depth_limit;
  std::uint32_t parallel_depth;
};

void add_events(const format::Box3f& box, std::uint32_t prim, EventLists& out) {
  for (int k = 0; k < 3; ++k) {
    if (format::at(box.min, k) == format::at(box.max, k)) {
      out[k].push_back({format::at(box.min, k), prim, kPlanar});
    } else {
      out[k].push_back({format::at(box.min, k), prim, kStart});
      out[k].push_back({format::at(box.max, k), prim, kEnd});
    }
  }
}

// Every triangle has exactly one start or planar event on each axis.
std::size_t triangle_count(const EventLists& events) {
  std::size_t n = 0;
  for (const Event& e : events[0]) n += e.type != kEnd;
  return n;
}

Split find_split(const Context& ctx, const format::Box3f& cell, const EventLists& events,
                 std::size_t n) {
  const auto& o = ctx.options;
  const float inv_area = 1.0f / cell.half_area();
  auto cost = [&](float pl, float pr, std::size_t nl, std::size_t nr) {
    const float bonus = (nl == 0 || nr == 0) ? 1.0f - o.empty_bonus : 1.0f;
    return bonus * (o.traversal_cost + o.intersection_cost * (pl * float(nl) + pr * float(nr)));
  };
  Split best;
  for (int k = 0; k < 3; ++k) {
    const std::vector<Event>& list = events[k];
    std::size_t nl = 0, nr = n;
    for (std::size_t i = 0; i < list.size();) {
      const float p = list[i].pos;
      std::size_t ends = 0, planars = 0, starts = 0;
      for (; i < list.size() && list[i].pos == p && list[i].type == kEnd; ++i) ++ends;
      for (; i < list.size() && list[i].pos == p && list[i].type == kPlanar; ++i) ++planars;
      for (; i < list.size() && list[i].pos == p && list[i].type == kStart; ++i) ++starts;
      nr -= planars + ends;
      // Planes on the cell's faces cut nothing off; skipping them guarantees progress.
      if (p > format::at(cell.min, k) && p < format::at(cell.max, k)) {
        format::Box3f left = cell, right = cell;
        format::at(left.max, k) = p;
        format::at(right.min, k) = p;
        const float pl = left.half_area() * inv_area, pr = right.half_area() * inv_area;
        const float planar_left = cost(pl, pr, nl + planars, nr);
        const float planar_right = cost(pl, pr, nl, nr + planars);
        const float c = std::min(planar_left, planar_right);
        if (c < best.cost) best = {k, p, planar_left <= planar_right, c};
      }
      nl += starts + planars;
    }
  }
  return best;
}

void build_node(const Context& ctx, const format::Box3f& cell, EventLists events,
                std::uint32_t depth, Subtree& out, std::vector<std::uint8_t>& side);

void emit_leaf(const EventLists& events, Subtree& out) {
  const auto first = std::uint32_t(out.prims.size());
  for (const Event& e : events[0])
    if (e.type != kEnd) out.prims.push_back(e.prim);
  std::sort(out.prims.begin() + first, out.prims.end());
  const std::size_t count = out.prims.size() - first;
  if (count > format::kKdMaxIndex || out.prims.size() > std::size_t{0xFFFFFFFF})
    throw std::runtime_error("k-d tree: more references than the layout can address");
  out.nodes.push_back(format::KdNode::leaf(first, std::uint32_t(count)));
}

// Appends `sub` (built with indices relative to itself) at the end of `out`.
void append(Subtree& out, const Subtree& sub) {
  const auto node_offset = std::uint32_t(out.nodes.size());
  const auto prim_offset = std::uint32_t(out.prims.size());
  if (out.nodes.size() + sub.nodes.size() > format::kKdMaxIndex)
    throw std::runtime_error("k-d tree: more nodes than the layout can address");
  for (format::KdNode n : sub.nodes) {
    n = n.is_leaf()
            ? format::KdNode::leaf(n.first_reference() + prim_offset, n.reference_count())
            : format::KdNode::interior(int(n.axis()), n.split(), n.above_child() + node_offset);
    out.nodes.push_back(n);
  }
  out.prims.insert(out.prims.end(), sub.prims.begin(), sub.prims.end());
}

void build_node(const Context& ctx, const format::Box3f& cell, EventLists events,
                std::uint32_t depth, Subtree& out, std::vector<std::uint8_t>& side) {
  const std::size_t n = triangle_count(events);
  const Split split =
      n == 0 || depth >= ctx.depth_limit ? Split{} : find_split(ctx, cell, events, n);
  if (!(split.cost < ctx.options.intersection_cost * float(n))) {
    emit_leaf(events, out);
    return;
  }
  const int axis = split.axis;
  const float p = split.pos;

  // Classify by the split axis's events; what is neither left- nor right-only straddles.
  std::vector<std::uint32_t> straddling;
  for (const Event& e : events[axis]) {
    if (e.type == kEnd && e.pos <= p) {
      side[e.prim] = kLeftOnly;
    } else if (e.type == kStart && e.pos >= p) {
      side[e.prim] = kRightOnly;
    } else if (e.type == kPlanar) {
      side[e.prim] = e.pos < p           ? kLeftOnly
                     : e.pos > p         ? kRightOnly
                     : split.planar_left ? kLeftOnly
                                         : kRightOnly;
    }
  }
  for (const Event& e : events[axis])
    if (e.type == kStart && side[e.prim] == kBoth) straddling.push_back(e.prim);

  format::Box3f left_cell = cell, right_cell = cell;
  format::at(left_cell.max, axis) = p;
  format::at(right_cell.min, axis) = p;
  // Each list sized before it is filled: one allocation per list, not one per doubling (the
  // deep nodes' lists are short and many; under the sanitizers allocation dominated the build).
  EventLists left, right;
  for (int k = 0; k < 3; ++k) {
    std::size_t sides[3] = {0, 0, 0};
    for (const Event& e : events[k]) ++sides[side[e.prim]];
    left[k].reserve(sides[kLeftOnly] + 2 * straddling.size());
    right[k].reserve(sides[kRightOnly] + 2 * straddling.size());
    for (const Event& e : events[k]) {
      if (side[e.prim] == kLeftOnly)
        left[k].push_back(e);
      else if (side[e.prim] == kRightOnly)
        right[k].push_back(e);
    }
  }
  for (const Event& e : events[axis]) side[e.prim] = kBoth;
  events = {};

  // Straddling triangles get fresh events from their part inside each child; a triangle whose
  // box straddles but whose surface misses a child is left out of it.
  EventLists left_new, right_new;
  for (int k = 0; k < 3; ++k)
    left_new[k].reserve(2 * straddling.size()), right_new[k].reserve(2 * straddling.size());
  for (const std::uint32_t prim : straddling) {
    const format::Triangle& t = ctx.scene.triangles[prim];
    const auto& v = ctx.scene.positions;
    const format::Box3f lb = clip_triangle_to_box(v[t.v[0]], v[t.v[1]], v[t.v[2]], left_cell);
    const format::Box3f rb = clip_triangle_to_box(v[t.v[0]], v[t.v[1]], v[t.v[2]], right_cell);
    if (!lb.empty()) add_events(lb, prim, left_new);
    if (!rb.empty()) add_events(rb, prim, right_new);
  }
  auto merge_into = [](std::vector<Event>& list, std::vector<Event>& extra) {
    if (extra.empty()) return;
    std::sort(extra.begin(), extra.end());
    // Merged from the back into the list's reserved room (inplace_merge would allocate).
    std::size_t i = list.size(), j = extra.size(), w = i + j;
    list.resize(w);
    while (j > 0) list[--w] = i > 0 && extra[j - 1] < list[i - 1] ? list[--i] : extra[--j];
    extra = {};
  };
  for (int k = 0; k < 3; ++k) {
    merge_into(left[k], left_new[k]);
    merge_into(right[k], right_new[k]);
  }

  const std::size_t index = out.nodes.size();
  out.nodes.emplace_back();
  const bool spawn = depth < ctx.parallel_depth && left[0].size() >= kParallelEvents &&
                     right[0].size() >= kParallelEvents;
  if (spawn) {
    // The above side builds into its own subtree (with its own side marks), appended after.
    Subtree above;
    fork_join(
        true, [&] { build_node(ctx, left_cell, std::move(left), depth + 1, out, side); },
        [&] {
          std::vector<std::uint8_t> own_side(side.size(), kBoth);
          build_node(ctx, right_cell, std::move(right), depth + 1, above, own_side);
        });
    const auto above_index = std::uint32_t(out.nodes.size());
    append(out, above);
    out.nodes[index] = format::KdNode::interior(axis, p, above_index);
  } else {
    build_node(ctx, left_cell, std::move(left), depth + 1, out, side);
    const std::size_t above_index = out.nodes.size();
    if (above_index > format::kKdMaxIndex)
      throw std::runtime_error("k-d tree: more nodes than the layout can address");
    build_node(ctx, right_cell, std::move(right), depth + 1, out, side);
    out.nodes[index] = format::KdNode::interior(axis, p, std::uint32_t(above_index));
  }
}

// Statistics and the SAH cost from the finished layout, walking cells down from the root.
void measure(const FlatKdTree& tree, const KdTreeBuildOptions& o, KdTreeStatistics& s) {
  const double root_area = tree.bounds.half_area();
  struct Pending {
    std::uint32_t node, depth;
    format::Box3f cell;
  };
  std::vector<Pending> stack{{0, 1, tree.bounds}};
  double cost = 0;
  while (!stack.empty()) {
    const Pending p = stack.back();
    stack.pop_back();
    const format::KdNode& n = tree.nodes[p.node];
    s.max_depth = std::max(s.max_depth, p.depth);
    const double area = root_area > 0 ? p.cell.half_area() / root_area : 0;
    if (n.is_leaf()) {
      s.leaf_count += 1;
      s.empty_leaf_count += n.reference_count() == 0;
      s.largest_leaf = std::max(s.largest_leaf, n.reference_count());
      cost += o.intersection_cost * area * n.reference_count();
      continue;
    }
    cost += o.traversal_cost * area;
    format::Box3f below = p.cell, above = p.cell;
    format::at(below.max, n.axis()) = n.split();
    format::at(above.min, n.axis()) = n.split();
    stack.push_back({n.above_child(), p.depth + 1, above});
    stack.push_back({p.node + 1, p.depth + 1, below});
  }
  s.sah_cost = cost;
}

}  // namespace

std::uint32_t kd_depth_limit(std::size_t triangle_count) {
  const double limit = 8.0 + 1.3 * std::log2(double(std::max<std::size_t>(triangle_count, 1)));
  return std::min(format::kKdMaxDepth - 1, std::uint32_t(std::lround(limit)));
}

FlatKdTree build_kdtree(const Scene& scene, const KdTreeBuildOptions& options) {
  if (scene.triangles.empty()) throw std::runtime_error("k-d tree: the scene has no triangles");
  FlatKdTree tree;
  tree.bounds.grow(scene.bounds.min);
  tree.bounds.grow(scene.bounds.max);
  EventLists events;
  for (auto& list : events) list.reserve(2 * scene.triangles.size());
  tree.triangles.reserve(scene.triangles.size());
  for (std::uint32_t i = 0; i < scene.triangles.size(); ++i) {
    const format::Triangle& t = scene.triangles[i];
    const auto& v = scene.positions;
    tree.triangles.push_back({v[t.v[0]], v[t.v[1]], v[t.v[2]]});
    format::Box3f box;
    for (const auto corner : t.v) box.grow(v[corner]);
    add_events(box, i, events);
  }
  for (auto& list : events) std::sort(list.begin(), list.end());

  const Context ctx{scene, options, kd_depth_limit(scene.triangles.size()),
                    fork_depth(options.threads)};
  Subtree root;
  std::vector<std::uint8_t> side(scene.triangles.size(), kBoth);
  build_node(ctx, tree.bounds, std::move(events), 1, root, side);
  tree.nodes = std::move(root.nodes);
  tree.prim_ids = std::move(root.prims);

  KdTreeStatistics& s = tree.stats;
  s.depth_limit = ctx.depth_limit;
  s.node_count = tree.nodes.size();
  s.reference_count = tree.prim_ids.size();
  s.references_per_triangle = double(s.reference_count) / double(scene.triangles.size());
  s.bytes_per_triangle = double(tree.nodes.size() * sizeof(format::KdNode) +
                                tree.prim_ids.size() * sizeof(std::uint32_t) +
                                tree.triangles.size() * sizeof(format::RayTriangle)) /
                         double(scene.triangles.size());
  measure(tree, options, s);
  return tree;
}

}  // namespace kiln
