// The SBVH's top-down construction (Stich, Friedrich, Dietrich 2009) on presorted per-axis
// reference arrays: sorted once at the root, kept sorted through every object and spatial split,
// so the exact SAH sweep never sorts per node.
#include <cmath>
#include <optional>
#include <stdexcept>

#include "bvh_splits.hpp"
#include "bvh_subtree.hpp"
#include "huge_pages.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln {

namespace {

// Subtrees at least this large (both sides of a split) go to their own thread whenever a worker
// slot is free, at any depth (bvh_subtree.hpp's WorkerSlots). Each subtree is a pure function of
// its references, so the tree is the same whatever runs where.
constexpr std::size_t kParallelSubtree = 4096;

// The nodes and primitive ids of a subtree, emitted depth-first (first child adjacent); leaf
// offsets index `prims`, interior offsets `nodes`, both from 0 for a subtree built apart.
struct FlatOut {
  std::vector<format::BvhNode> nodes;
  std::vector<std::uint32_t> prims;
};
std::size_t emitted_nodes(const FlatOut& out) {
  return out.nodes.size();
}

struct BuildContext {
  const Scene& scene;
  const BvhBuildOptions& options;
  float root_area;
  WorkerSlots& slots;  // threads not yet working: large nodes' axes and forks take them
  PendingRightsOf<FlatOut>& pending;  // right subtrees a thread with nothing to do may build
};

// The free worker slots a large node takes for its sweeps, spatial binning and partitions, given
// back when it is done (also when it throws).
struct SlotsTaken {
  WorkerSlots& slots;
  unsigned extra;
  SlotsTaken(WorkerSlots& s, bool large) : slots(s), extra(large ? s.take_all() : 0u) {}
  ~SlotsTaken() { slots.give(extra); }
  unsigned threads() const { return 1 + extra; }
};

format::Box3f bounds_of(std::span<const PrimRef> refs) {
  format::Box3f box;
  for (const auto& r : refs) box.grow(r.box);
  return box;
}

format::BvhNode node_of(const format::Box3f& box) {
  format::BvhNode node{};
  for (int a = 0; a < 3; ++a)
    node.min[a] = format::at(box.min, a), node.max[a] = format::at(box.max, a);
  return node;
}

void append_leaf(const format::Box3f& box, std::span<const PrimRef> refs, FlatOut& out) {
  format::BvhNode node = node_of(box);
  node.offset = std::uint32_t(out.prims.size());
  node.count = std::uint16_t(refs.size());
  out.nodes.push_back(node);
  for (const auto& r : refs) out.prims.push_back(r.prim);
}

// Appends a subtree built apart, shifting its offsets past what `out` holds.
// Both arrays are sized once (on huge pages when large) and filled in place: growing them node
// by node regrew and copied the root's arrays after its halves joined, serially.
void append_subtree(FlatOut& out, const FlatOut& sub) {
  const std::size_t nodes = out.nodes.size(), prims = out.prims.size();
  const auto node_shift = std::uint32_t(nodes), prim_shift = std::uint32_t(prims);
  if (out.nodes.capacity() < nodes + sub.nodes.size()) {
    std::vector<format::BvhNode> grown;
    reserve_huge(grown, nodes + sub.nodes.size());
    grown.assign(out.nodes.begin(), out.nodes.end());
    out.nodes.swap(grown);
  }
  out.nodes.resize(nodes + sub.nodes.size());
  format::BvhNode* to = out.nodes.data() + nodes;
  for (format::BvhNode n : sub.nodes) {
    n.offset += n.count == 0 ? node_shift : prim_shift;
    *to++ = n;
  }
  if (out.prims.capacity() < prims + sub.prims.size()) {
    std::vector<std::uint32_t> grown;
    reserve_huge(grown, prims + sub.prims.size());
    grown.assign(out.prims.begin(), out.prims.end());
    out.prims.swap(grown);
  }
  out.prims.insert(out.prims.end(), sub.prims.begin(), sub.prims.end());
}

// How a node splits: by the SAH sweep, a spatial split, halves (no SAH split), or not at all.
struct Choice {
  ObjectSplit object;
  SpatialSplit spatial;
  int order_axis = 0;  // the order a leaf keeps and a spatial split visits references in
};

Choice choose_split(const BuildContext& ctx, const SortedRefs& refs, const format::Box3f& box,
                    std::size_t budget, unsigned threads) {
  const auto& o = ctx.options;
  Choice c;
  c.object = find_sweep_split(refs, box, o, threads);
  if (c.object.valid()) c.order_axis = c.object.axis;
  if (budget > 0) {
    const float overlap =
        c.object.valid()
            ? format::Box3f::intersection(c.object.left_box, c.object.right_box).half_area()
            : box.half_area();
    if (!c.object.valid() || overlap > o.sbvh_alpha * ctx.root_area)
      c.spatial = find_spatial_split(refs.axis[c.order_axis], box, ctx.scene, o, c.object.axis,
                                     threads, c.object.cost);
  }
  return c;
}

// Whether a node of n references (at most max_leaf_size) stays a leaf: by the SAH with a test
// per reference, or (leaf_packet) with leaves priced per packet against the object split (the
// spatial split's counts are not known; below kMinSpatialRefs it is not searched at all).
bool leaf_wins(const BvhBuildOptions& o, const Choice& c, const format::Box3f& box, std::size_t n,
               float best_cost) {
  if (o.leaf_packet == 0 || !c.object.valid()) return best_cost >= o.intersection_cost * float(n);
  return packet_leaf_wins(o, n, box.half_area(), c.object.left_box.half_area(), c.object.left_count,
                          c.object.right_box.half_area());
}

void build_children(const BuildContext& ctx, SortedRefs left, SortedRefs right, std::uint32_t depth,
                    std::size_t budget, std::size_t index, FlatOut& out);

void build_node(const BuildContext& ctx, SortedRefs refs, std::uint32_t depth, std::size_t budget,
                FlatOut& out) {
  const auto& o = ctx.options;
  const format::Box3f box = bounds_of(refs.axis[0]);
  const std::size_t n = refs.size();
  const bool must_stop = depth + 1 >= format::kBvhMaxDepth;
  if (n <= 1 || must_stop) {
    if (n > format::kBvhMaxLeafSize)
      throw std::runtime_error("BVH: " + std::to_string(n) + " references left at maximum depth");
    return append_leaf(box, refs.axis[0], out);
  }
  // A large node's axes run apart on the threads that are free.
  std::optional<SlotsTaken> taken(std::in_place, ctx.slots, n >= kParallelSweep);
  const unsigned threads = taken->threads();
  const Choice c = choose_split(ctx, refs, box, budget, threads);
  const float best_cost = std::min(c.object.cost, c.spatial.cost);
  const auto& ordered = refs.axis[c.order_axis];
  SortedRefs left, right;
  bool spatial = false;
  if (!c.object.valid() && !c.spatial.valid()) {
    // All centroids coincide: nothing separates them by the SAH, so split the list in half.
    if (n <= o.max_leaf_size) return append_leaf(box, ordered, out);
    partition_object_split(std::move(refs), c.order_axis, n / 2, left, right, threads);
  } else if (n <= o.max_leaf_size && leaf_wins(o, c, box, n, best_cost)) {
    return append_leaf(box, ordered, out);
  } else if (c.spatial.valid() && c.spatial.cost < c.object.cost) {
    const std::size_t added =
        apply_spatial_split(c.spatial, refs, c.order_axis, ctx.scene, left, right, threads);
    budget -= std::min(budget, added);
    if (left.size() == 0 || right.size() == 0) {  // unsplitting moved everything to one side
      if (!c.object.valid()) return append_leaf(box, ordered, out);
      left.clear(), right.clear();
    } else {
      spatial = true;
    }
  }
  if (left.size() == 0 && right.size() == 0)
    partition_object_split(std::move(refs), c.object.axis, c.object.left_count, left, right,
                           threads);
  const int axis = spatial ? c.spatial.axis : std::max(c.object.axis, 0);
  refs.clear();   // free before recursing
  taken.reset();  // the slots go back before the children fork
  const std::size_t index = out.nodes.size();
  out.nodes.push_back(node_of(box));  // made interior below
  out.nodes[index].axis = std::uint8_t(axis);
  build_children(ctx, std::move(left), std::move(right), depth, budget, index, out);
}

// The children of the node at `index`, the duplication budget shared in proportion to size
// (deterministic, no global counter). Left and right subtrees are built apart and only then
// appended: the nodes are the same whether or not the right one ran on its own thread.
void build_children(const BuildContext& ctx, SortedRefs left, SortedRefs right, std::uint32_t depth,
                    std::size_t budget, std::size_t index, FlatOut& out) {
  const std::size_t left_budget = budget * left.size() / (left.size() + right.size());
  const auto left_tree = [&](FlatOut& o) {
    build_node(ctx, std::move(left), depth + 1, left_budget, o);
  };
  const auto right_tree = [&](FlatOut& o) {
    build_node(ctx, std::move(right), depth + 1, budget - left_budget, o);
  };
  // Both halves large: the right one may go to a free thread, or be listed for one that
  // finishes its own part early (an uneven split left a core idle until the other thread
  // reached a split that could fork).
  const bool large = left.size() >= kParallelSubtree && right.size() >= kParallelSubtree;
  const std::uint32_t second = emit_children_scheduled(
      ctx.slots, large, &ctx.pending, right.size(), out, left_tree, right_tree,
      [](FlatOut& o, const FlatOut& sub) { append_subtree(o, sub); });
  out.nodes[index].offset = second;
}

}  // namespace

const char* bvh_builder_name(BvhBuilder builder) {
  switch (builder) {
    case BvhBuilder::kBinned:
      return "binned";
    case BvhBuilder::kSweep:
      return "sweep";
    case BvhBuilder::kSpatial:
      return "sbvh";
  }
  return "?";
}

std::vector<format::BvhNode> build_sbvh_nodes(const Scene& scene, const BvhBuildOptions& options,
                                              std::vector<std::uint32_t>& prim_ids) {
  if (scene.triangles.empty()) throw std::runtime_error("BVH: the scene has no triangles");
  std::vector<PrimRef> refs = huge_vector<PrimRef>(scene.triangles.size());
  // In fixed chunks, their bounds merged in order: the bounds of one pass in order.
  constexpr std::size_t kChunk = 65536;
  std::vector<format::Box3f> chunk_box((refs.size() + kChunk - 1) / kChunk);
  parallel_for(chunk_box.size(), options.threads, [&](std::size_t c) {
    for (std::size_t i = c * kChunk; i < std::min(refs.size(), (c + 1) * kChunk); ++i) {
      for (const auto v : scene.triangles[i].v) refs[i].box.grow(scene.positions[v]);
      refs[i].prim = std::uint32_t(i);
      chunk_box[c].grow(refs[i].box);
    }
  });
  format::Box3f root;
  for (const format::Box3f& b : chunk_box) root.grow(b);
  WorkerSlots slots(resolve_thread_count(options.threads));
  PendingRightsOf<FlatOut> pending;
  const BuildContext ctx{scene, options, root.half_area(), slots, pending};
  SortedRefs sorted;  // sorted once here, kept sorted through every split
  // Three axes on two threads would leave one idle for a third of the time: on several
  // threads each axis is sorted in turn by all of them.
  const unsigned threads = resolve_thread_count(options.threads);
  for (int a = 0; a < 3; ++a) sort_by_centroid(refs, a, sorted.axis[a], threads);
  refs = {};
  const std::size_t budget = std::size_t(double(scene.triangles.size()) *
                                         std::max(0.0, double(options.sbvh_max_duplication)));
  FlatOut out;
  build_node(ctx, std::move(sorted), 0, budget, out);
  prim_ids = std::move(out.prims);
  return std::move(out.nodes);
}

}  // namespace kiln
