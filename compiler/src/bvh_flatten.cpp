// The flat BVH (pbrt-style: pre-order, first child adjacent, second child's index stored) from
// the binned, sweep or SBVH builder, leaf triangles copied in leaf order, and the statistics
// every builder reports.
#include <algorithm>
#include <optional>
#include <stdexcept>

#include "bvh_binned_build.hpp"
#include "bvh_evh_presplit.hpp"
#include "huge_pages.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln {

namespace {

// One reference per triangle (its box and id), in parallel: each index writes its own slot.
std::vector<PrimRef> triangle_refs(const Scene& scene, unsigned threads) {
  std::vector<PrimRef> refs(scene.triangles.size());
  parallel_for_batched(refs.size(), 65536, threads, [&](std::size_t i) {
    PrimRef r;
    for (const auto v : scene.triangles[i].v) r.box.grow(scene.positions[v]);
    r.prim = std::uint32_t(i);
    refs[i] = r;
  });
  return refs;
}

// Triangles and primitive ids in leaf order.
void copy_leaf_triangles(const Scene& scene, FlatBvh& out, unsigned threads) {
  out.triangles.resize(out.prim_ids.size());
  parallel_for_batched(out.prim_ids.size(), 65536, threads, [&](std::size_t i) {
    const auto& t = scene.triangles[out.prim_ids[i]];
    out.triangles[i] = {scene.positions[t.v[0]], scene.positions[t.v[1]], scene.positions[t.v[2]]};
  });
}

// The build references: one per triangle, or the EVH presplit's pieces.
std::vector<PrimRef> build_refs(const Scene& scene, const BvhBuildOptions& options) {
  return options.presplit == BvhPresplit::kEvh ? evh_presplit_refs(scene, options)
                                               : triangle_refs(scene, options.threads);
}

// A presplit leaf may hold several pieces of one triangle: keep the first of each and compact.
// Leaves lie in pre-order over consecutive reference ranges, so entries only move down.
void dedupe_leaf_references(std::vector<format::BvhNode>& nodes,
                            std::vector<std::uint32_t>& prim_ids) {
  std::uint32_t write = 0;
  for (format::BvhNode& node : nodes) {
    if (node.count == 0) continue;
    const std::uint32_t start = write;
    for (std::uint32_t i = node.offset, end = node.offset + node.count; i < end; ++i) {
      const auto kept_begin = prim_ids.begin() + start, kept_end = prim_ids.begin() + write;
      if (std::find(kept_begin, kept_end, prim_ids[i]) == kept_end) prim_ids[write++] = prim_ids[i];
    }
    node.offset = start;
    node.count = std::uint16_t(write - start);
  }
  prim_ids.resize(write);
}

// The binned builder on its own 32-byte references, made straight from the triangles (or from
// the presplit's pieces, whose PrimRef array goes before the build).
// Without a presplit, `counts` gets the nodes' statistics as the build counts them.
std::size_t build_binned_flat_nodes(const Scene& scene, const BvhBuildOptions& options,
                                    FlatBvh& out, std::optional<BvhStatistics>& counts) {
  bvh_simd::BuildRefs pieces_refs;  // with a presplit: made from its pieces
  std::span<bvh_simd::BuildRef> refs;
  if (options.presplit == BvhPresplit::kNone) {
    // The references' block is reserved (not touched) for the collapse's per-node records, up
    // to 40 bytes for each of 1.25 nodes per reference (as build_binned_nodes reserves its
    // nodes), and handed on in `spare` after the build.
    const std::size_t n = scene.triangles.size();
    refs = triangle_build_refs(scene, options.threads, out.spare, 40 * (n + n / 4 + 1));
    counts.emplace();
  } else {
    const std::vector<PrimRef> pieces = build_refs(scene, options);
    pieces_refs.resize(pieces.size());
    for (std::size_t i = 0; i < pieces.size(); ++i)
      pieces_refs[i] = bvh_simd::BuildRef::make(pieces[i].box, pieces[i].prim);
    refs = pieces_refs;
  }
  reserve_huge(out.prim_ids, refs.size());
  out.prim_ids.resize(refs.size());
  out.nodes = build_binned_nodes(refs, options, counts ? &*counts : nullptr, out.prim_ids);
  return refs.size();
}

// The sweep or binned builder's nodes and primitive ids in leaf order; returns the number of
// build references. `counts`: the nodes' statistics where the builder counted them.
std::size_t build_flat_nodes(const Scene& scene, const BvhBuildOptions& options, FlatBvh& out,
                             std::optional<BvhStatistics>& counts) {
  if (options.builder == BvhBuilder::kSpatial) {
    out.nodes = build_sbvh_nodes(scene, options, out.prim_ids);
    return out.prim_ids.size();
  }
  if (options.builder == BvhBuilder::kSweep) {
    std::vector<PrimRef> refs = build_refs(scene, options);
    out.nodes = build_sweep_nodes(refs, out.prim_ids, options);  // reference indices
    for (std::uint32_t& id : out.prim_ids) id = refs[id].prim;
    return refs.size();  // the references (28 B each) go before the triangles are copied
  }
  return build_binned_flat_nodes(scene, options, out, counts);
}

}  // namespace

namespace {

// The counts and depths of the nodes: they lie in pre-order (first child adjacent), so one pass
// in index order visits them as a depth-first walk would; a node passes its depth on.
void count_nodes(std::span<const format::BvhNode> nodes, BvhStatistics& s) {
  std::vector<std::uint8_t> depth(nodes.size());
  if (!nodes.empty()) depth[0] = 1;
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    const format::BvhNode& n = nodes[i];
    s.max_depth = std::max<std::uint32_t>(s.max_depth, depth[i]);
    if (n.count != 0) {
      s.leaf_count += 1;
      s.reference_count += n.count;
      s.max_leaf_size = std::max<std::uint32_t>(s.max_leaf_size, n.count);
    } else {
      depth[i + 1] = depth[n.offset] = std::uint8_t(depth[i] + 1);
    }
  }
}

// The SAH cost, summed in index order (a depth-first walk's order, as the binned build counts it).
double sah_cost_of(std::span<const format::BvhNode> nodes, const BvhBuildOptions& options) {
  const double root_area = nodes.empty() ? 0.0 : bvh_node_half_area(nodes[0]);
  double sum = 0;
  for (const format::BvhNode& n : nodes) sum += bvh_sah_term(n, n.count != 0, root_area, options);
  return sum;
}

// The averages and sizes from the counts.
void finish_statistics(BvhStatistics& s, std::size_t node_count, std::size_t triangles) {
  s.average_leaf_size = s.leaf_count ? double(s.reference_count) / double(s.leaf_count) : 0;
  s.duplication_factor = triangles ? double(s.reference_count) / double(triangles) : 0;
  s.bytes_per_triangle =
      triangles
          ? double(node_count * sizeof(format::BvhNode) +
                   s.reference_count * (sizeof(format::RayTriangle) + sizeof(std::uint32_t))) /
                double(triangles)
          : 0;
}

}  // namespace

BvhStatistics flat_bvh_statistics(std::span<const format::BvhNode> nodes, std::size_t triangles,
                                  const BvhBuildOptions& options) {
  BvhStatistics s;
  s.node_count = nodes.size();
  // The ordered SAH sum (a chain of additions) runs beside the pass over the depths and counts
  // on two threads or more.
  const bool apart = resolve_thread_count(options.threads) > 1 && nodes.size() >= 65536;
  fork_join(
      apart, [&] { count_nodes(nodes, s); }, [&] { s.sah_cost = sah_cost_of(nodes, options); });
  finish_statistics(s, nodes.size(), triangles);
  return s;
}

FlatBvh build_bvh(const Scene& scene, const BvhBuildOptions& options) {
  if (scene.triangles.empty()) throw std::runtime_error("BVH: the scene has no triangles");
  if (options.builder == BvhBuilder::kSpatial && options.presplit != BvhPresplit::kNone)
    throw std::invalid_argument("BVH: a presplit needs the binned or sweep builder");
  FlatBvh out;
  std::optional<BvhStatistics> counts;
  const std::size_t references = build_flat_nodes(scene, options, out, counts);
  if (options.presplit != BvhPresplit::kNone) dedupe_leaf_references(out.nodes, out.prim_ids);
  // The binned and sweep builders partition one reference per triangle.
  out.distinct_refs =
      options.builder != BvhBuilder::kSpatial && options.presplit == BvhPresplit::kNone;
  if (options.leaf_triangles) copy_leaf_triangles(scene, out, options.threads);
  if (counts) {
    out.stats = *counts;
    finish_statistics(out.stats, out.nodes.size(), scene.triangles.size());
  } else {
    out.stats = flat_bvh_statistics(out.nodes, scene.triangles.size(), options);
  }
  if (options.presplit != BvhPresplit::kNone) out.stats.presplit_references = references;
  return out;
}

}  // namespace kiln
