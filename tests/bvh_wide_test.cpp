// The wide BVH (bvh/sbvh with width 4 or 8): every kernel against brute force and watertight,
// the collapse keeps every reference, proximity queries equal the binary BVH's, forged nodes and
// a forced kernel the CPU lacks are refused. Kernel agreement on the corpus: corpus_test.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <map>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/compiler/bvh_collapse.hpp"
#include "kiln/formats/bvh_wide.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/bvh_wide.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/manifest.hpp"
#include "ray_fixtures.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

using format::Float3;

constexpr BvhKernel kKernels[] = {BvhKernel::kScalar, BvhKernel::kSse, BvhKernel::kAvx2,
                                  BvhKernel::kAvx512};
constexpr BvhBuilder kBuilders[] = {BvhBuilder::kBinned, BvhBuilder::kSpatial};

// As `kiln build` makes it: the binary tree down to packet-priced leaves (leaf_packet 4), unless
// `leaf_packet` says otherwise (0: down to single references).
FlatWideBvh wide_of(const Scene& scene, BvhBuilder builder, std::uint32_t width,
                    bool quantized = false, std::uint32_t leaf_packet = format::kBvhPacketSize) {
  BvhBuildOptions o;
  o.builder = builder;
  o.leaf_packet = leaf_packet;
  return collapse_bvh(build_bvh(scene, o), width, scene.triangles.size(), quantized);
}

BvhWideView view_of(const FlatWideBvh& w, BvhKernel kernel) {
  return BvhWideView(w.width, w.quantized, w.arena, "test", kernel);
}

// Runs `check(view)` for each width, box encoding (16-wide: float, SBVH only), builder and kernel
// this CPU has (saying which it skips), on trees built as `kiln build` builds them, and (8-wide
// float boxes) on trees built down to single references.
template <class Check>
void for_each_layout(const Scene& scene, Check&& check) {
  for (const std::uint32_t width : {4u, 8u, 16u})
    for (const bool quantized : {false, true})
      for (const BvhBuilder builder : kBuilders)
        for (const std::uint32_t leaf_packet : {format::kBvhPacketSize, 0u}) {
          // 16-wide: float boxes only, and one builder (the node test does not depend on it).
          if (width == 16 && (quantized || builder != BvhBuilder::kSpatial)) continue;
          if (leaf_packet == 0 && (width != 8 || quantized)) continue;
          const FlatWideBvh wide = wide_of(scene, builder, width, quantized, leaf_packet);
          for (const BvhKernel kernel : kKernels) {
            if (!bvh_kernel_supported(kernel)) {
              std::printf("skipped: this CPU cannot run the %s kernel\n", bvh_kernel_name(kernel));
              continue;
            }
            SCOPED_TRACE(std::to_string(width) + "-wide " + (quantized ? "u8 " : "float ") +
                         bvh_builder_name(builder) + " " + bvh_kernel_name(kernel) +
                         " leaf_packet " + std::to_string(leaf_packet));
            check(view_of(wide, kernel));
          }
        }
}

TEST(WideBvh, EveryKernelAgreesWithBruteForceOnGeneratedWorstCases) {
  for (const auto& [name, scene] : test::worst_cases()) {
    SCOPED_TRACE(name);
    const auto rays = test::box_rays(scene, 400);
    for_each_layout(scene, [&](const BvhWideView& view) {
      test::expect_agrees_with_brute_force(scene, view, rays);
    });
  }
}

TEST(WideBvh, EveryKernelIsWatertightThroughVerticesAndEdges) {
  const Scene sphere = test::icosphere(4);
  std::vector<Float3> targets = sphere.positions;
  for (const auto& t : sphere.triangles)
    for (int e = 0; e < 3; ++e) {
      const Float3 a = sphere.positions[t.v[e]], b = sphere.positions[t.v[(e + 1) % 3]];
      targets.push_back({(a.x + b.x) * 0.5f, (a.y + b.y) * 0.5f, (a.z + b.z) * 0.5f});
    }
  const Float3 origins[] = {{0, 0, 0}, {0.1f, -0.2f, 0.05f}, {-0.3f, 0.25f, 0.4f}};
  for_each_layout(sphere, [&](const BvhWideView& view) {
    std::size_t misses = 0;
    for (const Float3& o : origins)
      for (const Float3& target : targets) {
        const Ray ray{o, 0.0f, {target.x - o.x, target.y - o.y, target.z - o.z}, INFINITY};
        misses += !view.intersect(ray).hit();
        misses += !view.occluded(ray);
      }
    EXPECT_EQ(misses, 0u);
  });
}

// The primitive ids of every packet lane in the arena, leaf by leaf in depth-first order.
std::vector<std::uint32_t> lane_ids(const BvhWideView& view) {
  std::vector<std::uint32_t> ids;
  auto collect = [&](const auto& n) {
    for (int k = 0; k < int(view.width()); ++k)
      if (n.child[k] & format::kBvhLeafFlag)
        for (const format::BvhTrianglePacket& p : view.leaf(n.child[k], n.packets[k]))
          ids.insert(ids.end(), p.prim, p.prim + format::kBvhPacketSize);
  };
  if (view.width() == 16)
    view.for_each_node<format::BvhNode16>(collect);
  else if (view.width() == 8)
    view.for_each_node<format::BvhNode8>(collect);
  else
    view.for_each_node<format::BvhNode4>(collect);
  return ids;
}

// Every node's used slots by non-increasing surface area (WideSlotOrder::kLargestArea).
template <int W>
void expect_largest_first(const FlatWideBvh& w) {
  for (std::size_t i = 0; i < w.stats.node_count; ++i) {
    format::BvhWideNode<W> n;
    std::memcpy(&n, w.nodes.data() + i * sizeof n, sizeof n);
    double previous = INFINITY;
    for (int k = 0; k < W; ++k) {
      if (n.child[k] == format::kBvhLeafFlag && n.packets[k] == 0) continue;  // empty slot
      const float dx = n.bounds[0][1][k] - n.bounds[0][0][k];
      const float dy = n.bounds[1][1][k] - n.bounds[1][0][k];
      const float dz = n.bounds[2][1][k] - n.bounds[2][0][k];
      const double area = dx * dy + dy * dz + dz * dx;  // as the collapse computes it
      EXPECT_LE(area, previous) << "node " << i << " slot " << k;
      previous = area;
    }
  }
}

TEST(WideBvh, CollapseKeepsEveryReferenceInPackets) {
  const Scene scene = test::icosphere(3);
  for (const BvhBuilder builder : kBuilders) {
    BvhBuildOptions o;
    o.builder = builder;
    const FlatBvh binary = build_bvh(scene, o);
    for (const std::uint32_t width : {4u, 8u, 16u})
      for (const bool greedy : {false, true}) {
        WideCollapseOptions c;
        c.greedy = greedy;
        c.order = greedy ? WideSlotOrder::kTree : WideSlotOrder::kLargestArea;
        const FlatWideBvh wide =
            collapse_bvh(binary, width, scene.triangles.size(), false, nullptr, c);
        const BvhWideView view = view_of(wide, BvhKernel::kScalar);
        std::vector<std::uint32_t> a = binary.prim_ids, b = lane_ids(view);
        ASSERT_EQ(b.size(), wide.packets.size() * format::kBvhPacketSize);
        std::sort(a.begin(), a.end());
        std::sort(b.begin(), b.end());
        b.erase(std::unique(b.begin(), b.end()), b.end());
        a.erase(std::unique(a.begin(), a.end()), a.end());
        EXPECT_EQ(a, b);
        EXPECT_GT(wide.stats.packet_fill, 0.5);
        EXPECT_LE(wide.stats.max_depth, binary.stats.max_depth);
        if (!greedy && width == 8) expect_largest_first<8>(wide);
        if (!greedy && width == 4) expect_largest_first<4>(wide);
        if (!greedy && width == 16) expect_largest_first<16>(wide);
        // The arena holds the same tree: every node and packet.
        EXPECT_EQ(view.node_count(), wide.stats.node_count);
        EXPECT_EQ(view.packet_count(), wide.packets.size());
        EXPECT_EQ(wide.arena.size(), wide.stats.arena_bytes);
      }
  }
  EXPECT_THROW(collapse_bvh(build_bvh(scene, {}), 3, scene.triangles.size()),
               std::invalid_argument);
  EXPECT_THROW(collapse_bvh(build_bvh(scene, {}), 16, scene.triangles.size(), true),
               std::invalid_argument);
}

// Above 65,536 binary nodes the collapse sweeps subtrees on their own threads, and on more than
// one thread it writes the subtrees below the top levels in parallel: the same arena, tree by
// index and statistics as one thread (which sizes nothing first: it appends, growing the arena
// as it goes), for the programme and the greedy collapse.
TEST(WideBvh, CollapseIsTheSameOnAnyThreadCount) {
  const Scene scene = test::icosphere(6);  // 81,920 triangles
  BvhBuildOptions o;
  o.leaf_triangles = false;
  const FlatBvh binary = build_bvh(scene, o);
  ASSERT_GE(binary.nodes.size(), 65536u);
  for (const auto& [width, quantized, greedy] :
       {std::tuple{8u, false, false}, std::tuple{4u, true, false}, std::tuple{8u, false, true},
        std::tuple{16u, false, false}}) {
    std::vector<FlatWideBvh> wide;
    for (const unsigned threads : {1u, 2u, 8u}) {
      WideCollapseOptions c;
      c.threads = threads;
      c.greedy = greedy;
      wide.push_back(collapse_bvh(binary, width, scene.triangles.size(), quantized, &scene, c));
    }
    for (std::size_t i = 1; i < wide.size(); ++i) {
      EXPECT_EQ(wide[i].arena, wide[0].arena)
          << width << (quantized ? " u8" : "") << (greedy ? " greedy" : "");
      EXPECT_EQ(wide[i].nodes, wide[0].nodes);
      ASSERT_EQ(wide[i].packets.size(), wide[0].packets.size());
      EXPECT_EQ(0, std::memcmp(wide[i].packets.data(), wide[0].packets.data(),
                               wide[0].packets.size() * sizeof(format::BvhTrianglePacket)));
      EXPECT_EQ(wide[i].stats.node_count, wide[0].stats.node_count);
      EXPECT_EQ(wide[i].stats.packet_fill, wide[0].stats.packet_fill);
      EXPECT_EQ(wide[i].stats.max_depth, wide[0].stats.max_depth);
    }
    // Without the tree by index, the same arena.
    WideCollapseOptions c;
    c.threads = 2;
    c.greedy = greedy;
    c.index_tree = false;
    const FlatWideBvh arena_only =
        collapse_bvh(binary, width, scene.triangles.size(), quantized, &scene, c);
    EXPECT_EQ(arena_only.arena, wide[0].arena);
    EXPECT_TRUE(arena_only.nodes.empty() && arena_only.packets.empty());
    EXPECT_EQ(BvhWideView(width, quantized, wide[0].arena, "test", BvhKernel::kScalar).node_count(),
              wide[0].stats.node_count);
  }
}

// The wide tree's SAH cost under the collapse's own model, summed over the stored nodes: every
// interior child costs its area x node_cost, every leaf its area x packet_cost x its packets.
template <int W>
double wide_sah(const FlatWideBvh& w, const WideCollapseOptions& c) {
  double cost = 0;
  for (std::size_t i = 0; i < w.stats.node_count; ++i) {
    format::BvhWideNode<W> n;
    std::memcpy(&n, w.nodes.data() + i * sizeof n, sizeof n);
    for (int k = 0; k < W; ++k) {
      if (n.child[k] == format::kBvhLeafFlag && n.packets[k] == 0) continue;  // empty slot
      float lo[3], hi[3];
      format::bvh_child_box(n, k, lo, hi);
      const double dx = hi[0] - lo[0], dy = hi[1] - lo[1], dz = hi[2] - lo[2];
      const double area = dx * dy + dy * dz + dz * dx;
      cost += (n.child[k] & format::kBvhLeafFlag) ? area * c.packet_cost * n.packets[k]
                                                  : area * c.node_cost;
    }
  }
  return cost;
}

// The dynamic programme is optimal over the cuts of the binary tree, and the greedy expansion's
// tree is one of them: its cost can only be lower or equal, on every mesh and cost setting.
TEST(WideBvh, DistinctReferencesAreMarkedAndCollapseAsWhenLookedFor) {
  const Scene scene = test::icosphere(5);
  for (const auto& [builder, presplit] : {std::pair{BvhBuilder::kBinned, BvhPresplit::kNone},
                                          std::pair{BvhBuilder::kSweep, BvhPresplit::kNone},
                                          std::pair{BvhBuilder::kBinned, BvhPresplit::kEvh},
                                          std::pair{BvhBuilder::kSpatial, BvhPresplit::kNone}}) {
    BvhBuildOptions o;
    o.builder = builder, o.presplit = presplit, o.leaf_triangles = false;
    FlatBvh binary = build_bvh(scene, o);
    std::vector<std::uint32_t> ids = binary.prim_ids;
    std::sort(ids.begin(), ids.end());
    const bool distinct = std::adjacent_find(ids.begin(), ids.end()) == ids.end();
    // Marked only where the builder guarantees it, and then true.
    EXPECT_EQ(binary.distinct_refs,
              builder != BvhBuilder::kSpatial && presplit == BvhPresplit::kNone);
    if (binary.distinct_refs) {
      EXPECT_TRUE(distinct);
    }
    for (const unsigned threads : {1u, 2u}) {
      WideCollapseOptions c;
      c.threads = threads;
      const FlatWideBvh marked = collapse_bvh(binary, 16, scene.triangles.size(), false, &scene, c);
      FlatBvh unmarked = binary;
      unmarked.distinct_refs = false;  // every leaf's repeats looked for
      EXPECT_EQ(collapse_bvh(unmarked, 16, scene.triangles.size(), false, &scene, c).arena,
                marked.arena)
          << int(builder) << " " << int(presplit) << " " << threads;
    }
  }
}

// The binned build hands its finished reference array on (FlatBvh::spare), and a collapse given it
// as scratch keeps its per-node records there: the same arena as with blocks of its own, whatever
// the block held before (filled with a pattern here) and also when it is too small for them.
TEST(WideBvh, ScratchBlockGivesTheSameArena) {
  std::map<std::string, Scene> scenes = test::worst_cases();
  scenes.emplace("icosphere", test::icosphere(5));
  for (const auto& [name, scene] : scenes) {
    SCOPED_TRACE(name);
    BvhBuildOptions o;
    o.leaf_triangles = false;
    o.leaf_packet = format::kBvhPacketSize;  // as `kiln build` builds for the wide layouts
    FlatBvh binary = build_bvh(scene, o);
    // Reserved for 40-byte records of 1.25 nodes per reference (bvh_builder.hpp); trees of
    // one-reference leaves (no leaf_packet) have up to 2 per reference and outgrow it.
    EXPECT_GE(binary.spare.capacity(), 40 * (scene.triangles.size() * 5 / 4));
    for (const std::uint32_t width : {4u, 8u, 16u}) {
      for (const unsigned threads : {1u, 2u}) {
        WideCollapseOptions c;
        c.threads = threads;
        const FlatWideBvh own =
            collapse_bvh(binary, width, scene.triangles.size(), false, &scene, c);
        binary.spare.resize(binary.spare.capacity());
        std::memset(binary.spare.data(), 0xA5, binary.spare.size());
        c.scratch = &binary.spare;
        EXPECT_EQ(collapse_bvh(binary, width, scene.triangles.size(), false, &scene, c).arena,
                  own.arena)
            << width << " " << threads;
        UninitializedVector<std::byte> small(64);
        c.scratch = &small;
        EXPECT_EQ(collapse_bvh(binary, width, scene.triangles.size(), false, &scene, c).arena,
                  own.arena)
            << width << " " << threads << " (scratch too small)";
      }
    }
  }
}

TEST(WideBvh, SahCollapseCostsNoMoreThanTheGreedyCollapse) {
  std::map<std::string, Scene> scenes = test::worst_cases();
  scenes.emplace("icosphere", test::icosphere(4));
  for (const auto& [name, scene] : scenes) {
    SCOPED_TRACE(name);
    const FlatBvh binary = build_bvh(scene, {});  // binned: no duplicate references
    for (const double packet_cost : {0.5, 1.0, 2.0}) {
      WideCollapseOptions dp, greedy;
      dp.packet_cost = greedy.packet_cost = packet_cost;
      greedy.greedy = true;
      const FlatWideBvh a = collapse_bvh(binary, 8, scene.triangles.size(), false, nullptr, dp);
      const FlatWideBvh b = collapse_bvh(binary, 8, scene.triangles.size(), false, nullptr, greedy);
      const double ca = wide_sah<8>(a, dp), cb = wide_sah<8>(b, dp);
      EXPECT_LE(ca, cb * (1 + 1e-9)) << "packet cost " << packet_cost;
      EXPECT_LE(a.packets.size(), b.packets.size() + b.packets.size() / 2);
    }
  }
}

// The programme's costs by its recurrence alone, every share of every slot count tried (the
// collapse skips shares and slot counts that cannot win): cost[i][k - 1] is binary subtree i's
// least cost over at most k slots.
struct ReferenceProgramme {
  const FlatBvh& bin;
  const WideCollapseOptions& o;
  int width;
  std::vector<std::vector<double>> cost;
  std::vector<std::uint32_t> refs;
  std::vector<char> leaf;  // the subtree is one leaf (given one slot)

  ReferenceProgramme(const FlatBvh& b, const WideCollapseOptions& opt, int w)
      : bin(b), o(opt), width(w), cost(b.nodes.size()), refs(b.nodes.size()), leaf(b.nodes.size()) {
    visit(0);
  }

  void visit(std::uint32_t i) {
    const format::BvhNode& n = bin.nodes[i];
    const float dx = n.max[0] - n.min[0], dy = n.max[1] - n.min[1], dz = n.max[2] - n.min[2];
    const double area = dx * dy + dy * dz + dz * dx;
    if (n.count == 0) visit(i + 1), visit(n.offset);
    refs[i] = n.count > 0 ? n.count : refs[i + 1] + refs[n.offset];
    const double packets = double((refs[i] + format::kBvhPacketSize - 1) / format::kBvhPacketSize);
    const double as_leaf = area * (o.leaf_cost + o.packet_cost * packets);
    cost[i].assign(std::size_t(width), as_leaf);
    leaf[i] = n.count > 0;
    if (n.count > 0) return;
    const std::vector<double>&l = cost[i + 1], &r = cost[n.offset];
    std::vector<double> spread(std::size_t(width) + 1, INFINITY);
    for (int k = 2; k <= width; ++k)
      for (int left = 1; left < k; ++left)
        spread[k] = std::min(spread[k], l[left - 1] + r[k - left - 1]);
    const double inner = area * o.node_cost + spread[width];
    leaf[i] = refs[i] <= o.max_leaf_refs && as_leaf <= inner;
    cost[i][0] = leaf[i] ? as_leaf : inner;
    for (int k = 2; k <= width; ++k) cost[i][k - 1] = std::min(cost[i][k - 2], spread[k]);
  }
};

// The collapse's SAH cost is the reference programme's, to the bit, on every width, builder and
// cost setting; and (binned: no duplicate references, so the model's packets are the stored
// ones) the tree it writes costs that: its picks are the least cost's. (The shortcuts the
// collapse takes, shares beyond a child's slots and slot counts beyond a node's, must not change
// a bit.)
TEST(WideBvh, ProgrammeCostIsTheRecurrencesLeast) {
  std::map<std::string, Scene> scenes = test::worst_cases();
  scenes.emplace("icosphere", test::icosphere(4));
  for (const auto& [name, scene] : scenes)
    for (const BvhBuilder builder : kBuilders)
      for (const double packet_cost : {0.5, 2.0}) {
        BvhBuildOptions b;
        b.builder = builder;
        const FlatBvh binary = build_bvh(scene, b);
        const format::BvhNode& root = binary.nodes[0];
        const float dx = root.max[0] - root.min[0], dy = root.max[1] - root.min[1],
                    dz = root.max[2] - root.min[2];
        const float root_area = dx * dy + dy * dz + dz * dx;
        for (const int width : {4, 8, 16}) {
          SCOPED_TRACE(name + " " + bvh_builder_name(builder) + " width " + std::to_string(width) +
                       " packet cost " + std::to_string(packet_cost));
          WideCollapseOptions c;
          c.packet_cost = packet_cost;
          const FlatWideBvh wide =
              collapse_bvh(binary, std::uint32_t(width), scene.triangles.size(), false, nullptr, c);
          const ReferenceProgramme ref(binary, c, width);
          EXPECT_EQ(wide.stats.sah_cost, ref.cost[0][0] / root_area);
          if (builder != BvhBuilder::kBinned) continue;
          double stored = width == 4   ? wide_sah<4>(wide, c)
                          : width == 8 ? wide_sah<8>(wide, c)
                                       : wide_sah<16>(wide, c);
          if (!ref.leaf[0]) stored += double(root_area) * c.node_cost;  // the root node's own
          // (The stored boxes' areas in double, the programme's in float: 1e-6 apart at most.)
          EXPECT_NEAR(stored / root_area, wide.stats.sah_cost, 1e-6 * wide.stats.sah_cost);
        }
      }
}

// Every quantised child box contains the float box it encodes.
TEST(WideBvh, QuantizedBoxesContainTheFloatBoxes) {
  const Scene scene = test::icosphere(4);
  for (const BvhBuilder builder : kBuilders) {
    const FlatWideBvh exact = wide_of(scene, builder, 8), q = wide_of(scene, builder, 8, true);
    ASSERT_EQ(exact.nodes.size(), 2 * q.nodes.size());
    const auto* a = reinterpret_cast<const format::BvhNode8*>(exact.nodes.data());
    const auto* b = reinterpret_cast<const format::BvhQNode8*>(q.nodes.data());
    for (std::size_t i = 0; i < q.nodes.size() / sizeof(format::BvhQNode8); ++i)
      for (int k = 0; k < 8; ++k) {
        EXPECT_EQ(a[i].child[k], b[i].child[k]);
        if (a[i].child[k] == format::kBvhLeafFlag && a[i].packets[k] == 0) continue;
        float lo[3], hi[3], qlo[3], qhi[3];
        format::bvh_child_box(a[i], k, lo, hi);
        format::bvh_child_box(b[i], k, qlo, qhi);
        for (int axis = 0; axis < 3; ++axis) {
          EXPECT_LE(qlo[axis], lo[axis]);
          EXPECT_GE(qhi[axis], hi[axis]);
        }
      }
  }
}

TEST(WideBvh, ProximityQueriesEqualTheBinaryBvh) {
  const Scene scene = test::icosphere(3);
  const FlatBvh flat = build_bvh(scene, {});
  const BvhView binary(flat.nodes, flat.triangles, flat.prim_ids);
  for (const auto& [width, quantized] :
       {std::pair{4u, false}, std::pair{8u, false}, std::pair{4u, true}, std::pair{8u, true},
        std::pair{16u, false}}) {
    const FlatWideBvh wide = collapse_bvh(flat, width, scene.triangles.size(), quantized);
    const BvhWideView view = view_of(wide, BvhKernel::kScalar);
    for (const Ray& r : test::box_rays(scene, 200)) {
      const ClosestPoint a = closest_point(binary, r.org), b = closest_point(view, r.org);
      EXPECT_EQ(a.prim, b.prim);
      EXPECT_EQ(a.distance, b.distance);
      EXPECT_EQ(point_inside(binary, r.org), point_inside(view, r.org));
      const Float3 lo{r.org.x - 0.3f, r.org.y - 0.3f, r.org.z - 0.3f};
      const Float3 hi{r.org.x + 0.3f, r.org.y + 0.3f, r.org.z + 0.3f};
      std::vector<std::uint32_t> in_a, in_b;
      triangles_in_box(binary, lo, hi, in_a);
      triangles_in_box(view, lo, hi, in_b);
      EXPECT_EQ(in_a, in_b);
    }
  }
}

// Arenas rewritten by hand: each forgery must be refused when the view is created.
TEST(WideBvh, ForgedArenasAreRefused) {
  const Scene scene = test::icosphere(3);
  const FlatWideBvh wide = wide_of(scene, BvhBuilder::kBinned, 4);
  ASSERT_GT(wide.stats.node_count, 2u);
  const BvhWideView clean = view_of(wide, BvhKernel::kScalar);
  using Bytes = std::vector<std::byte>;
  using Node = format::BvhNode4;
  // The root's first interior slot; the first node (in depth-first order) with a leaf, and that
  // slot.
  int interior = -1, leaf = -1;
  std::size_t leaf_node = 0;
  for (int k = 0; k < 4 && interior < 0; ++k)
    if (!(clean.node<Node>(0).child[k] & format::kBvhLeafFlag)) interior = k;
  clean.for_each_node<Node>([&](const Node& n) {
    for (int k = 0; k < 4 && leaf < 0; ++k)
      if ((n.child[k] & format::kBvhLeafFlag) && n.packets[k] > 0) {
        leaf = k;
        leaf_node = std::size_t(reinterpret_cast<const std::byte*>(&n) - clean.arena().data());
      }
  });
  ASSERT_GE(interior, 0);
  ASSERT_GE(leaf, 0);
  auto expect_refused = [&](const char* what, std::size_t at, auto&& forge) {
    Bytes bad(wide.arena.begin(), wide.arena.end());
    forge(bad, *reinterpret_cast<Node*>(bad.data() + at));
    EXPECT_THROW(BvhWideView(4, false, bad, "test", BvhKernel::kScalar), BlobError) << what;
  };
  expect_refused("child out of range", 0,
                 [&](Bytes&, Node& n) { n.child[interior] = 0x7FFFFFF0u; });
  expect_refused("cycle to the root", 0, [&](Bytes&, Node& n) { n.child[interior] = 0; });
  expect_refused("a child one line late", 0, [&](Bytes&, Node& n) { n.child[interior] += 4; });
  expect_refused("a wrong prefetch hint", 0, [&](Bytes&, Node& n) { n.packets[interior] ^= 1; });
  expect_refused("the arena cut short", 0, [&](Bytes& b, Node&) { b.resize(b.size() - 64); });
  expect_refused("a line after the last node", 0,
                 [&](Bytes& b, Node&) { b.resize(b.size() + 64); });
  expect_refused("leaf packets out of range", leaf_node,
                 [&](Bytes&, Node& n) { n.packets[leaf] = 255; });
  expect_refused("leaf packets not after the node", leaf_node,
                 [&](Bytes&, Node& n) { n.child[leaf] += 10; });
  expect_refused("an empty slot with an offset", leaf_node,
                 [&](Bytes&, Node& n) { n.packets[leaf] = 0; });
  const Bytes part(wide.arena.begin(), wide.arena.begin() + 64);
  EXPECT_THROW(BvhWideView(4, false, part, "test", BvhKernel::kScalar), BlobError) << "a part";
  EXPECT_THROW(BvhWideView(4, false, {}, "test", BvhKernel::kScalar), BlobError) << "empty";

  // A chain of nodes deeper than the traversal stack allows: node i's only child is node i + 1,
  // the last one's a leaf of one packet right after it.
  auto chain = [](std::uint32_t depth) {
    constexpr std::size_t kNode = sizeof(Node), kPacket = sizeof(format::BvhTrianglePacket);
    std::vector<std::byte> arena(depth * kNode + 192);  // the packet, padded to the line
    for (std::uint32_t i = 0; i < depth; ++i) {
      Node n{};
      for (int a = 0; a < 3; ++a)
        for (int k = 0; k < 4; ++k) n.bounds[a][0][k] = INFINITY, n.bounds[a][1][k] = -INFINITY;
      for (int k = 0; k < 4; ++k) n.child[k] = format::kBvhLeafFlag;
      if (i + 1 < depth) {
        n.child[0] = (i + 1) * kNode / format::kBvhArenaUnit;
        n.packets[0] = i + 2 == depth ? (kPacket + 63) / 64 : 0;  // the last node's leaf lines
      } else {
        n.child[0] = format::kBvhLeafFlag | depth * kNode / format::kBvhArenaUnit;
        n.packets[0] = 1;
      }
      std::memcpy(arena.data() + i * kNode, &n, sizeof n);
    }
    return arena;
  };
  const std::vector<std::byte> too_deep = chain(format::kBvhMaxDepth + 1),
                               deepest = chain(format::kBvhMaxDepth);
  EXPECT_THROW(BvhWideView(4, false, too_deep, "test", BvhKernel::kScalar), BlobError)
      << "too deep";
  EXPECT_NO_THROW(BvhWideView(4, false, deepest, "test", BvhKernel::kScalar));
}

// The same forgery through a blob with valid checksums: open cannot see it, the view refuses it.
TEST(WideBvh, ForgedNodeInABlobIsRefusedWhenViewed) {
  const Scene scene = test::icosphere(2);
  const auto blob = test::blob_with(scene, "bvh:width=8", 2);
  const AlignedBuffer clean = test::aligned_copy(blob);
  const Blob original = Blob::open_memory(clean.bytes());
  const auto& d = desc_of<schema::BvhDesc>(original, original.structures()[0]);
  ASSERT_EQ(d.width(), 8u);
  const AlignedBuffer forged =
      test::forged_copy(blob, d.wide_arena(), offsetof(format::BvhNode8, child), 0u);
  const Blob b = Blob::open_memory(forged.bytes(), "forged.kiln");
  EXPECT_THROW(BvhWideView::from_blob(b, "bvh"), BlobError);
  EXPECT_THROW(BvhView::from_blob(original, "bvh"), BlobError) << "a binary view of a wide BVH";
}

// A 16-wide BVH through a blob: opened, deep-checked, and the same closest distances and
// occlusion as the 8-wide one; a forged node and 8-bit boxes at width 16 are refused.
TEST(WideBvh, SixteenWideBlobOpensVerifiesAndTracesAsTheEightWide) {
  const Scene scene = test::icosphere(3);
  const AlignedBuffer b16 = test::aligned_copy(test::blob_with(scene, "sbvh:width=16", 2));
  const AlignedBuffer b8 = test::aligned_copy(test::blob_with(scene, "sbvh:width=8", 2));
  const Blob blob16 = Blob::open_memory(b16.bytes()), blob8 = Blob::open_memory(b8.bytes());
  const auto& d = desc_of<schema::BvhDesc>(blob16, blob16.structures()[0]);
  ASSERT_EQ(d.width(), 16u);
  EXPECT_NO_THROW(blob16.verify());
  const std::string name = blob16.structures()[0].name;
  const BvhWideView wide16 = BvhWideView::from_blob(blob16, name, BvhKernel::kScalar);
  const BvhWideView wide8 = BvhWideView::from_blob(blob8, name, BvhKernel::kScalar);
  for (const Ray& r : test::box_rays(scene, 300)) {
    const Hit a = wide16.intersect(r), b = wide8.intersect(r);
    EXPECT_EQ(a.hit(), b.hit());
    EXPECT_EQ(a.t, b.t);  // the least t of all triangles hit (which of exact ties: visit order)
    EXPECT_EQ(wide16.occluded(r), wide8.occluded(r));
  }
  EXPECT_THROW(BvhWideView(16, true, wide16.arena(), "test", BvhKernel::kScalar), BlobError);
  const AlignedBuffer forged =
      test::forged_copy(test::blob_with(scene, "sbvh:width=16", 2), d.wide_arena(),
                        offsetof(format::BvhNode16, child), 0u);
  EXPECT_THROW(BvhWideView::from_blob(Blob::open_memory(forged.bytes(), "forged.kiln"), name),
               BlobError);
}

// A wide BVH of the layout before the arena (its description names BVWN/BVWT sections) is
// refused at open with the way out, in one line. Forged here by pointing the manifest's
// `wide_nodes` field at the stored arena index (the vtable entry), checksums recomputed.
TEST(WideBvh, TheLayoutBeforeTheArenaIsRefusedWithAMessage) {
  const Scene scene = test::icosphere(2);
  const auto blob = test::blob_with(scene, "sbvh:width=8", 2);
  const AlignedBuffer clean = test::aligned_copy(blob);
  const Blob original = Blob::open_memory(clean.bytes());
  const auto& d = desc_of<schema::BvhDesc>(original, original.structures()[0]);
  const auto* vtable = reinterpret_cast<const flatbuffers::Table&>(d).GetVTable();
  const std::uint16_t arena_field =
      flatbuffers::ReadScalar<std::uint16_t>(vtable + schema::BvhDesc::VT_WIDE_ARENA);
  ASSERT_NE(arena_field, 0);
  ASSERT_LT(schema::BvhDesc::VT_WIDE_NODES, flatbuffers::ReadScalar<std::uint16_t>(vtable));
  const std::size_t at =
      std::size_t(vtable + schema::BvhDesc::VT_WIDE_NODES -
                  reinterpret_cast<const std::uint8_t*>(original.section_bytes(0).data()));
  const std::string error = test::open_only(
      test::with_patched_section(blob, 0, at, std::as_bytes(std::span(&arena_field, 1))));
  EXPECT_NE(error.find("layout before the node arena"), std::string::npos) << error;
  EXPECT_NE(error.find("rebuild it with kiln build"), std::string::npos) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos) << error;
}

TEST(WideBvh, KernelChoiceFollowsTheEnvironment) {
  setenv("KILN_BVH_KERNEL", "scalar", 1);
  EXPECT_EQ(bvh_auto_kernel(), BvhKernel::kScalar);
  setenv("KILN_BVH_KERNEL", "mmx", 1);
  EXPECT_THROW(bvh_auto_kernel(), std::invalid_argument);
  unsetenv("KILN_BVH_KERNEL");
  EXPECT_NE(bvh_auto_kernel(), BvhKernel::kAuto);
  // 16-wide nodes: AVX-512 first where the CPU has it, AVX2 first for the narrower ones.
  if (bvh_kernel_supported(BvhKernel::kAvx512)) {
    EXPECT_EQ(bvh_auto_kernel(16), BvhKernel::kAvx512);
  }
  if (bvh_kernel_supported(BvhKernel::kAvx2)) {
    EXPECT_EQ(bvh_auto_kernel(8), BvhKernel::kAvx2);
  }
  for (const BvhKernel k : kKernels)
    if (!bvh_kernel_supported(k)) {
      setenv("KILN_BVH_KERNEL", bvh_kernel_name(k), 1);
      EXPECT_THROW(bvh_auto_kernel(), std::invalid_argument) << bvh_kernel_name(k);
      unsetenv("KILN_BVH_KERNEL");
    }
}

}  // namespace
}  // namespace kiln
