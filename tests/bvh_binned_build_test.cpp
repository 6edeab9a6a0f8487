// The binned SAH builder (SSE2 binning on 32-byte references, occupied-bin masks, in-place
// partition) against a naive binned SAH written out here, and its output on any thread count
// where large nodes bin in parallel chunks.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "kiln/compiler/bvh_builder.hpp"

namespace kiln {
namespace {

// Random triangles of mixed sizes in a box, some sharing a centroid coordinate (ties).
Scene random_scene(std::size_t n, std::uint32_t seed) {
  Scene scene;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> pos(-100.0f, 100.0f), size(0.01f, 5.0f);
  for (std::size_t i = 0; i < n; ++i) {
    format::Float3 c{pos(rng), pos(rng), i % 7 == 0 ? 0.0f : pos(rng)};
    const float s = i % 11 == 0 ? 20.0f * size(rng) : size(rng);
    const auto base = std::uint32_t(scene.positions.size());
    scene.positions.push_back(c);
    scene.positions.push_back({c.x + s, c.y + 0.3f * s, c.z});
    scene.positions.push_back({c.x, c.y + s, c.z + 0.5f * s});
    scene.triangles.push_back({{base, base + 1, base + 2}});
  }
  return scene;
}

format::Box3f triangle_box(const Scene& scene, std::uint32_t t) {
  format::Box3f b;
  for (const auto v : scene.triangles[t].v) b.grow(scene.positions[v]);
  return b;
}

// The root's best binned split, plainly: k bins per axis over the centroid bounds, every plane,
// the SAH; ties go to the first axis and plane. Returns the triangles on the left.
std::set<std::uint32_t> naive_root_left(const Scene& scene, std::uint32_t k) {
  const auto n = std::uint32_t(scene.triangles.size());
  format::Box3f bounds, centroids;
  for (std::uint32_t t = 0; t < n; ++t) {
    const format::Box3f b = triangle_box(scene, t);
    bounds.grow(b);
    centroids.grow(format::Float3{b.centroid(0), b.centroid(1), b.centroid(2)});
  }
  auto bin = [&](std::uint32_t t, int a) {
    const float extent = format::at(centroids.max, a) - format::at(centroids.min, a);
    const float c = triangle_box(scene, t).centroid(a);
    return std::min(k - 1, std::uint32_t(std::max(
                               0.0f, (c - format::at(centroids.min, a)) * (float(k) / extent))));
  };
  float best = std::numeric_limits<float>::infinity();
  int best_axis = -1;
  std::uint32_t best_plane = 0;
  for (int a = 0; a < 3; ++a) {
    for (std::uint32_t plane = 0; plane + 1 < k; ++plane) {
      format::Box3f l, r;
      std::size_t nl = 0;
      for (std::uint32_t t = 0; t < n; ++t) {
        if (bin(t, a) <= plane)
          l.grow(triangle_box(scene, t)), ++nl;
        else
          r.grow(triangle_box(scene, t));
      }
      if (nl == 0 || nl == n) continue;
      const float cost =
          1.0f + (l.half_area() * float(nl) + r.half_area() * float(n - nl)) / bounds.half_area();
      if (cost < best) best = cost, best_axis = a, best_plane = plane;
    }
  }
  std::set<std::uint32_t> left;
  for (std::uint32_t t = 0; t < n; ++t)
    if (bin(t, best_axis) <= best_plane) left.insert(t);
  return left;
}

// The triangles under the root's first child (the depth-first layout puts it at index 1).
std::set<std::uint32_t> built_root_left(const FlatBvh& bvh) {
  std::set<std::uint32_t> left;
  const std::uint32_t end = bvh.nodes[0].offset;  // the second child's index
  for (std::uint32_t i = 1; i < end; ++i) {
    const format::BvhNode& node = bvh.nodes[i];
    for (std::uint32_t j = 0; j < node.count; ++j) left.insert(bvh.prim_ids[node.offset + j]);
  }
  return left;
}

TEST(BvhBinnedBuild, RootSplitIsTheNaiveBinnedSahOptimum) {
  const Scene scene = random_scene(2000, 7);
  for (const std::uint32_t bins : {2u, 7u, 32u, 64u, 100u}) {  // 100: more than one mask word
    BvhBuildOptions options;
    options.bins = bins;
    const FlatBvh bvh = build_bvh(scene, options);
    ASSERT_EQ(bvh.nodes[0].count, 0) << bins;
    EXPECT_EQ(built_root_left(bvh), naive_root_left(scene, bins)) << bins << " bins";
  }
}

TEST(BvhBinnedBuild, SmallNodesBinIntoFewerBins) {
  EXPECT_EQ(object_bin_count(5, 32), 4u);
  EXPECT_EQ(object_bin_count(300, 32), 19u);
  EXPECT_EQ(object_bin_count(560, 32), 32u);
  EXPECT_EQ(object_bin_count(300, 7), 7u);
  EXPECT_EQ(object_bin_count(10, 2), 2u);
  // 300 references: the root bins into 4 + 300 / 20 = 19 bins, not 32 (or fewer if asked).
  const Scene scene = random_scene(300, 5);
  ASSERT_NE(naive_root_left(scene, 19), naive_root_left(scene, 32));  // the count shows
  for (const std::uint32_t bins : {32u, 7u}) {
    BvhBuildOptions options;
    options.bins = bins;
    const FlatBvh bvh = build_bvh(scene, options);
    ASSERT_EQ(bvh.nodes[0].count, 0) << bins;
    EXPECT_EQ(built_root_left(bvh), naive_root_left(scene, std::min(bins, 19u))) << bins;
  }
}

TEST(BvhBinnedBuild, SameTreeOnAnyThreadCountWithParallelChunkBinning) {
  // Above 2^18 references the top nodes bin in parallel chunks merged in order.
  const Scene scene = random_scene(270000, 11);
  std::vector<FlatBvh> built;
  for (const unsigned threads : {1u, 2u, 8u}) {
    BvhBuildOptions options;
    options.threads = threads;
    options.leaf_triangles = false;
    built.push_back(build_bvh(scene, options));
  }
  for (std::size_t i = 1; i < built.size(); ++i) {
    ASSERT_EQ(built[i].nodes.size(), built[0].nodes.size());
    EXPECT_EQ(0, std::memcmp(built[i].nodes.data(), built[0].nodes.data(),
                             built[0].nodes.size() * sizeof(format::BvhNode)));
    EXPECT_EQ(built[i].prim_ids, built[0].prim_ids);
  }
  // Every triangle exactly once, and each leaf's box holds its triangles.
  std::vector<std::uint32_t> ids = built[0].prim_ids;
  std::sort(ids.begin(), ids.end());
  ASSERT_EQ(ids.size(), scene.triangles.size());
  for (std::uint32_t i = 0; i < ids.size(); ++i) ASSERT_EQ(ids[i], i);
  for (const format::BvhNode& node : built[0].nodes) {
    for (std::uint32_t j = 0; j < node.count; ++j) {
      const format::Box3f b = triangle_box(scene, built[0].prim_ids[node.offset + j]);
      for (int a = 0; a < 3; ++a) {
        ASSERT_LE(node.min[a], format::at(b.min, a));
        ASSERT_GE(node.max[a], format::at(b.max, a));
      }
    }
  }
}

// The counts, depth and SAH cost the build counts as it emits the nodes (subtrees built on other
// threads counted once appended) are those of a depth-first walk over the finished nodes, and of
// flat_bvh_statistics' pass over them, to the bit, on any thread count.
TEST(BvhBinnedBuild, StatisticsCountedWhileBuildingAreThoseOfTheFinishedTree) {
  const Scene scene = random_scene(100000, 5);
  for (const std::uint32_t packet : {0u, 4u}) {
    for (const unsigned threads : {1u, 2u, 8u}) {
      BvhBuildOptions options;
      options.threads = threads;
      options.leaf_packet = packet;
      options.leaf_triangles = false;
      const FlatBvh bvh = build_bvh(scene, options);
      const auto& nodes = bvh.nodes;
      // The walk: pre-order from the root, depth 1 at the root, the SAH summed in visit order.
      const auto area = [](const format::BvhNode& n) {
        const double dx = double(n.max[0]) - n.min[0], dy = double(n.max[1]) - n.min[1],
                     dz = double(n.max[2]) - n.min[2];
        return dx < 0 || dy < 0 || dz < 0 ? 0.0 : dx * dy + dy * dz + dz * dx;
      };
      double sah = 0;
      std::uint64_t leaves = 0, references = 0;
      std::uint32_t depth = 0, largest = 0;
      std::vector<std::pair<std::uint32_t, std::uint32_t>> stack{{0, 1}};
      while (!stack.empty()) {
        const auto [i, d] = stack.back();
        stack.pop_back();
        const format::BvhNode& n = nodes[i];
        const double a = area(n) / area(nodes[0]);
        depth = std::max(depth, d);
        if (n.count != 0) {
          sah += a * options.intersection_cost * double(n.count);
          leaves += 1, references += n.count, largest = std::max<std::uint32_t>(largest, n.count);
        } else {
          sah += a * options.traversal_cost;
          stack.push_back({n.offset, d + 1});
          stack.push_back({i + 1, d + 1});
        }
      }
      const BvhStatistics pass = flat_bvh_statistics(nodes, scene.triangles.size(), options);
      const BvhStatistics& s = bvh.stats;
      const std::string at = std::to_string(threads) + " threads, packet " + std::to_string(packet);
      EXPECT_EQ(s.node_count, nodes.size()) << at;
      EXPECT_EQ(s.leaf_count, leaves) << at;
      EXPECT_EQ(s.reference_count, references) << at;
      EXPECT_EQ(s.max_depth, depth) << at;
      EXPECT_EQ(s.max_leaf_size, largest) << at;
      EXPECT_EQ(s.sah_cost, sah) << at;  // the same doubles summed in the same order
      EXPECT_EQ(pass.sah_cost, sah) << at;
      EXPECT_EQ(pass.max_depth, depth) << at;
      EXPECT_EQ(s.average_leaf_size, pass.average_leaf_size) << at;
      EXPECT_EQ(s.bytes_per_triangle, pass.bytes_per_triangle) << at;
      EXPECT_EQ(s.duplication_factor, pass.duplication_factor) << at;
    }
  }
}

// Two references: a node that stays a leaf keeps them in input order; a split puts the one with
// the lower centroid on the first spread axis first (as binning and the in-place partition
// do), each child's box being its triangle's.
TEST(BvhBinnedBuild, TwoReferenceNodesKeepTheirOrderOrPutTheLowerCentroidFirst) {
  const auto two = [](format::Float3 a, format::Float3 b, float size) {
    Scene scene;
    for (const format::Float3 c : {a, b}) {
      const auto base = std::uint32_t(scene.positions.size());
      scene.positions.push_back(c);
      scene.positions.push_back({c.x + size, c.y, c.z});
      scene.positions.push_back({c.x, c.y + size, c.z + size});
      scene.triangles.push_back({{base, base + 1, base + 2}});
    }
    BvhBuildOptions options;
    options.leaf_triangles = false;
    return std::pair{scene, build_bvh(scene, options)};
  };
  // Overlapping: splitting costs 1 + about 2 > 2, so one leaf, in input order.
  const auto [overlap, leaf] = two({0.1f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, 10.0f);
  ASSERT_EQ(leaf.nodes.size(), 1u);
  EXPECT_EQ(leaf.prim_ids, (std::vector<std::uint32_t>{0, 1}));
  // Far apart, the second lower on x (the first axis they spread on): split, it goes first.
  const auto [apart, split] = two({50.0f, 0.0f, 0.0f}, {0.0f, 3.0f, 0.0f}, 1.0f);
  ASSERT_EQ(split.nodes.size(), 3u);
  EXPECT_EQ(split.nodes[0].axis, 0);
  EXPECT_EQ(split.prim_ids, (std::vector<std::uint32_t>{1, 0}));
  for (std::uint32_t i = 1; i < 3; ++i) {
    const format::Box3f b = triangle_box(apart, split.prim_ids[split.nodes[i].offset]);
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(split.nodes[i].min[a], format::at(b.min, a));
      EXPECT_EQ(split.nodes[i].max[a], format::at(b.max, a));
    }
  }
}

// References under each node of a flat BVH (depth-first, first child adjacent).
std::vector<std::uint32_t> references_under(const FlatBvh& bvh) {
  std::vector<std::uint32_t> refs(bvh.nodes.size());
  for (std::size_t i = bvh.nodes.size(); i-- > 0;) {
    const format::BvhNode& n = bvh.nodes[i];
    refs[i] = n.count > 0 ? n.count : refs[i + 1] + refs[n.offset];
  }
  return refs;
}

// Nodes whose references all share one centroid have no binned split on any axis (every axis
// masked in the sweep): the list is halved while longer than a leaf allows. Each triangle once,
// no empty leaf, and the same tree on any thread count.
TEST(BvhBinnedBuild, CoincidentCentroidsHalveTheList) {
  Scene scene = random_scene(300, 3);
  const auto base = std::uint32_t(scene.positions.size());
  scene.positions.push_back({1.0f, 2.0f, 3.0f});
  scene.positions.push_back({2.0f, 2.0f, 3.0f});
  scene.positions.push_back({1.0f, 3.0f, 3.0f});
  for (int i = 0; i < 100; ++i) scene.triangles.push_back({{base, base + 1, base + 2}});
  for (const std::uint32_t packet : {0u, 4u}) {
    std::vector<std::uint32_t> first_ids;
    for (const unsigned threads : {1u, 2u}) {
      BvhBuildOptions options;
      options.threads = threads;
      options.leaf_packet = packet;
      const FlatBvh bvh = build_bvh(scene, options);
      std::vector<std::uint32_t> ids = bvh.prim_ids;
      if (first_ids.empty()) first_ids = ids;
      EXPECT_EQ(ids, first_ids) << threads << " threads";
      std::sort(ids.begin(), ids.end());
      ASSERT_EQ(ids.size(), scene.triangles.size());
      for (std::uint32_t i = 0; i < ids.size(); ++i) ASSERT_EQ(ids[i], i);
      const std::vector<std::uint32_t> under = references_under(bvh);
      EXPECT_EQ(under[0], scene.triangles.size());
      std::size_t leaf_refs = 0;
      for (const format::BvhNode& n : bvh.nodes) {
        leaf_refs += n.count;
        if (n.count > 0) EXPECT_LE(n.count, options.max_leaf_size);
      }
      EXPECT_EQ(leaf_refs, scene.triangles.size());  // no leaf lost or counted twice
    }
  }
}

float half_area(const format::BvhNode& n) {
  const float x = n.max[0] - n.min[0], y = n.max[1] - n.min[1], z = n.max[2] - n.min[2];
  return x * y + y * z + z * x;
}

// The least sum of the half areas of two boxes holding the triangles of `ids`, over every way to
// part them in two, plainly (infinity for fewer than two).
float best_bipartition(const Scene& scene, const std::vector<std::uint32_t>& ids) {
  float best = std::numeric_limits<float>::infinity();
  const auto n = std::uint32_t(ids.size());
  for (std::uint32_t m = 1; n >= 2 && m + 1 < (1u << n); ++m) {
    format::Box3f l, r;
    for (std::uint32_t i = 0; i < n; ++i) (m >> i & 1 ? l : r).grow(triangle_box(scene, ids[i]));
    best = std::min(best, l.half_area() + r.half_area());
  }
  return best;
}

// Leaves priced per packet (what `kiln build` builds for the wide layouts): no leaf holds more
// than max_leaf_size references; every interior node of at most max_leaf_size references splits
// only where its children's boxes, each weighted by its packets, sum to less than its own box
// weighted by its packets; and (binned) no leaf of one packet could be parted in two boxes of
// less area, by a brute-force search. Every triangle is still in a leaf.
TEST(BvhBinnedBuild, PacketPricedLeavesSplitOnlyWhereTheySavePacketArea) {
  const Scene scene = random_scene(3000, 5);
  for (const BvhBuilder builder : {BvhBuilder::kBinned, BvhBuilder::kSpatial}) {
    SCOPED_TRACE(bvh_builder_name(builder));
    BvhBuildOptions options;
    options.builder = builder;
    options.leaf_packet = 4;
    const FlatBvh packets = build_bvh(scene, options);
    const std::vector<std::uint32_t> refs = references_under(packets);
    const auto blocks = [](std::uint32_t n) { return float((n + 3) / 4); };
    std::size_t small_leaves = 0;
    for (std::size_t i = 0; i < packets.nodes.size(); ++i) {
      const format::BvhNode& n = packets.nodes[i];
      if (n.count > 0) {
        ASSERT_LE(n.count, options.max_leaf_size) << i;
        if (builder != BvhBuilder::kBinned || n.count > 4) continue;
        const std::vector<std::uint32_t> ids(packets.prim_ids.begin() + n.offset,
                                             packets.prim_ids.begin() + n.offset + n.count);
        EXPECT_GE(best_bipartition(scene, ids), half_area(n)) << i;
        small_leaves += 1;
        continue;
      }
      if (refs[i] > options.max_leaf_size) continue;
      const format::BvhNode &l = packets.nodes[i + 1], &r = packets.nodes[n.offset];
      EXPECT_LT(half_area(l) * blocks(refs[i + 1]) + half_area(r) * blocks(refs[n.offset]),
                half_area(n) * blocks(refs[i]))
          << i;
    }
    if (builder == BvhBuilder::kBinned) {
      EXPECT_GT(small_leaves, 100u);
    }
    std::set<std::uint32_t> ids(packets.prim_ids.begin(), packets.prim_ids.end());
    EXPECT_EQ(ids.size(), scene.triangles.size());
  }
}

}  // namespace
}  // namespace kiln
