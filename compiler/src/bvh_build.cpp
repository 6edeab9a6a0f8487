// Top-down SAH construction shared by the three builders; they differ only in split finding.
#include <cmath>
#include <stdexcept>

#include "bvh_splits.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln {

namespace {

// Subtrees at least this large, near the root, are built on their own thread. Each subtree is a
// pure function of its references, so the tree is the same whatever runs where.
constexpr std::size_t kParallelSubtree = 16384;

struct BuildContext {
  const Scene& scene;
  const BvhBuildOptions& options;
  float root_area;
  unsigned parallel_depth;  // spawn threads above this depth
};

format::Box3f bounds_of(std::span<const PrimRef> refs) {
  format::Box3f box;
  for (const auto& r : refs) box.grow(r.box);
  return box;
}

std::unique_ptr<BvhBuildNode> make_leaf(const format::Box3f& box, std::span<const PrimRef> refs) {
  auto leaf = std::make_unique<BvhBuildNode>();
  leaf->box = box;
  leaf->prims.reserve(refs.size());
  for (const auto& r : refs) leaf->prims.push_back(r.prim);
  return leaf;
}

std::unique_ptr<BvhBuildNode> build_node(const BuildContext& ctx, std::vector<PrimRef> refs,
                                         std::uint32_t depth, std::size_t budget) {
  const auto& o = ctx.options;
  const format::Box3f box = bounds_of(refs);
  const std::size_t n = refs.size();
  const float leaf_cost = o.intersection_cost * float(n);
  const bool must_stop = depth + 1 >= format::kBvhMaxDepth;
  if (n <= 1 || must_stop) {
    if (n > format::kBvhMaxLeafSize)
      throw std::runtime_error("BVH: " + std::to_string(n) + " references left at maximum depth");
    return make_leaf(box, refs);
  }

  std::vector<PrimRef> left, right;
  ObjectSplit object;
  if (o.builder == BvhBuilder::kBinned) {
    object = find_binned_split(refs, box, o);
  } else {
    object = find_sweep_split(refs, box, o);  // sorts refs on the chosen axis
  }
  SpatialSplit spatial;
  if (o.builder == BvhBuilder::kSpatial && budget > 0) {
    const float overlap =
        object.valid() ? format::Box3f::intersection(object.left_box, object.right_box).half_area()
                       : box.half_area();
    if (!object.valid() || overlap > o.sbvh_alpha * ctx.root_area) {
      spatial = find_spatial_split(refs, box, ctx.scene, o);
    }
  }
  const float best_cost = std::min(object.cost, spatial.cost);
  if (!object.valid() && !spatial.valid()) {
    // All centroids coincide: nothing separates them by the SAH, so split the list in half.
    if (n <= o.max_leaf_size) return make_leaf(box, refs);
    left.assign(refs.begin(), refs.begin() + std::ptrdiff_t(n / 2));
    right.assign(refs.begin() + std::ptrdiff_t(n / 2), refs.end());
  } else if (best_cost >= leaf_cost && n <= o.max_leaf_size) {
    return make_leaf(box, refs);
  } else if (spatial.valid() && spatial.cost < object.cost) {
    const std::size_t added = apply_spatial_split(spatial, refs, ctx.scene, left, right);
    budget -= std::min(budget, added);
    if (left.empty() || right.empty()) {  // unsplitting moved everything to one side
      left.clear();
      right.clear();
      if (!object.valid()) return make_leaf(box, refs);
      spatial = {};
    }
  }
  if (left.empty() && right.empty()) {
    if (o.builder == BvhBuilder::kBinned) {
      apply_binned_split(object, refs, left, right);
    } else {
      left.assign(refs.begin(), refs.begin() + std::ptrdiff_t(object.left_count));
      right.assign(refs.begin() + std::ptrdiff_t(object.left_count), refs.end());
    }
  }
  const std::uint8_t axis = std::uint8_t(spatial.valid()  ? spatial.axis
                                         : object.valid() ? object.axis
                                                          : 0);
  refs = {};  // free before recursing

  // The duplication budget is shared in proportion to size: deterministic, no global counter.
  const std::size_t total = left.size() + right.size();
  const std::size_t left_budget = budget * left.size() / total;
  const std::size_t right_budget = budget - left_budget;
  auto node = std::make_unique<BvhBuildNode>();
  node->box = box;
  node->axis = axis;
  // Left and right subtrees are built apart and only then attached: the tree is the same
  // whether or not the right one ran on its own thread.
  fork_join(
      depth < ctx.parallel_depth && left.size() >= kParallelSubtree &&
          right.size() >= kParallelSubtree,
      [&] { node->child[0] = build_node(ctx, std::move(left), depth + 1, left_budget); },
      [&] { node->child[1] = build_node(ctx, std::move(right), depth + 1, right_budget); });
  return node;
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

std::unique_ptr<BvhBuildNode> build_bvh_tree(const Scene& scene, const BvhBuildOptions& options) {
  if (scene.triangles.empty()) throw std::runtime_error("BVH: the scene has no triangles");
  std::vector<PrimRef> refs(scene.triangles.size());
  for (std::uint32_t i = 0; i < refs.size(); ++i) {
    for (const auto v : scene.triangles[i].v) refs[i].box.grow(scene.positions[v]);
    refs[i].prim = i;
  }
  const format::Box3f root = bounds_of(refs);
  const BuildContext ctx{scene, options, root.half_area(), fork_depth(options.threads)};
  const std::size_t budget = options.builder == BvhBuilder::kSpatial
                                 ? std::size_t(double(scene.triangles.size()) *
                                               std::max(0.0, double(options.sbvh_max_duplication)))
                                 : 0;
  return build_node(ctx, std::move(refs), 0, budget);
}

}  // namespace kiln
