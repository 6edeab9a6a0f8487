// The edge volume heuristic presplit (Dammertz & Keller 2008) for the binned and sweep BVH
// builders: pieces cover their triangles, references per triangle stay under the option, every
// triangle is still found (against brute force), long diagonal slivers are split and small or
// axis-parallel triangles are not, the SAH cost drops on slivers, and the option reaches the
// manifest, the dump and the cache key.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>

#include "../compiler/src/bvh_evh_presplit.hpp"
#include "kiln/compiler/build.hpp"
#include "kiln/compiler/build_cache.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/compiler/bvh_collapse.hpp"
#include "kiln/compiler/structure_builder.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/tools/inspect.hpp"
#include "ray_fixtures.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

using format::Float3;
using namespace kiln::test;

constexpr BvhBuilder kBuilders[] = {BvhBuilder::kBinned, BvhBuilder::kSweep};

// 300 long thin triangles along random diagonals of the unit cube, and 300 small triangles
// (edges 0.01) scattered in it: the slivers' boxes are almost empty, the small ones' are not.
Scene sliver_scene() {
  std::mt19937 rng(2208);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::vector<Float3> p;
  std::vector<format::Triangle> t;
  for (int i = 0; i < 300; ++i) {
    const Float3 a{unit(rng), unit(rng), unit(rng)};
    const Float3 b{unit(rng), unit(rng), unit(rng)};
    const Float3 c{0.5f * (a.x + b.x) + 0.004f, 0.5f * (a.y + b.y) - 0.003f, 0.5f * (a.z + b.z)};
    add_triangle(p, t, a, b, c);
  }
  for (int i = 0; i < 300; ++i) {
    const Float3 a{unit(rng), unit(rng), unit(rng)};
    add_triangle(p, t, a, {a.x + 0.01f, a.y, a.z + 0.005f}, {a.x, a.y + 0.01f, a.z - 0.004f});
  }
  return make_scene(p, t);
}

constexpr std::size_t kSlivers = 300;

BvhBuildOptions evh_options(BvhBuilder builder, std::uint32_t max_refs = 8, unsigned threads = 2) {
  BvhBuildOptions o;
  o.builder = builder;
  o.presplit = BvhPresplit::kEvh;
  o.evh_max_refs = max_refs;
  o.threads = threads;
  return o;
}

std::vector<std::uint32_t> refs_per_triangle(const std::vector<PrimRef>& refs, std::size_t n) {
  std::vector<std::uint32_t> count(n, 0);
  for (const PrimRef& r : refs) count.at(r.prim) += 1;
  return count;
}

TEST(BvhEvh, SplitsLongDiagonalSliversAndLeavesSmallTrianglesAlone) {
  const Scene scene = sliver_scene();
  const auto refs = evh_presplit_refs(scene, evh_options(BvhBuilder::kBinned));
  const auto count = refs_per_triangle(refs, scene.triangles.size());
  std::size_t split_slivers = 0;
  for (std::size_t i = 0; i < scene.triangles.size(); ++i) {
    if (i < kSlivers)
      split_slivers += count[i] > 1;
    else
      EXPECT_EQ(count[i], 1u) << "small triangle " << i;
  }
  EXPECT_GT(split_slivers, kSlivers * 9 / 10);
  EXPECT_GT(refs.size(), scene.triangles.size() * 3 / 2);
  // A large triangle in an axis plane has zero edge volumes: its box is already tight.
  const Float3 flat[3] = {{0, 0, 0}, {1, 1, 0}, {-1, 2, 0}};
  EXPECT_EQ(evh_piece_count(flat, 0.0, 8), 1u);
  const Float3 diagonal[3] = {{0, 0, 0}, {1, 1, 1}, {0.5f, 0.5f, 0.51f}};
  EXPECT_EQ(evh_piece_count(diagonal, 1.0, 64), 1u);  // largest edge volume 1: not above
  EXPECT_GT(evh_piece_count(diagonal, 0.99, 64), 1u);
  const auto loose = evh_piece_count(diagonal, 1e-2, 64),
             tight = evh_piece_count(diagonal, 1e-4, 64);
  EXPECT_LT(loose, tight);
  EXPECT_LE(tight, 64u);
  EXPECT_EQ(edge_volume({0, 0, 0}, {1, -2, 3}), 6.0);
}

TEST(BvhEvh, ReferencesPerTriangleAreBoundedByTheOption) {
  const Scene scene = sliver_scene();
  for (const std::uint32_t max_refs : {1u, 2u, 3u, 8u, 64u}) {
    SCOPED_TRACE(max_refs);
    const auto refs = evh_presplit_refs(scene, evh_options(BvhBuilder::kBinned, max_refs));
    const auto count = refs_per_triangle(refs, scene.triangles.size());
    EXPECT_LE(*std::max_element(count.begin(), count.end()), max_refs);
    if (max_refs > 1) {
      EXPECT_EQ(*std::max_element(count.begin(), count.end()), max_refs);
    } else {
      EXPECT_EQ(refs.size(), scene.triangles.size());
    }
    for (const auto builder : kBuilders) {
      const FlatBvh flat = build_bvh(scene, evh_options(builder, max_refs));
      EXPECT_EQ(flat.stats.presplit_references, refs.size());
      EXPECT_EQ(flat.prim_ids.size(), flat.stats.reference_count);
      std::vector<std::uint32_t> in_bvh(scene.triangles.size(), 0);
      for (const std::uint32_t id : flat.prim_ids) in_bvh.at(id) += 1;
      for (std::size_t i = 0; i < in_bvh.size(); ++i) {
        EXPECT_GE(in_bvh[i], 1u) << "triangle " << i << " lost";
        EXPECT_LE(in_bvh[i], count[i]);
      }
      for (const format::BvhNode& n : flat.nodes) {  // one reference per triangle per leaf
        if (n.count == 0) continue;
        std::vector<std::uint32_t> ids(flat.prim_ids.begin() + n.offset,
                                       flat.prim_ids.begin() + n.offset + n.count);
        std::sort(ids.begin(), ids.end());
        EXPECT_EQ(std::adjacent_find(ids.begin(), ids.end()), ids.end());
      }
    }
  }
}

// Random points of every triangle lie in the box of one of its references: the pieces' boxes
// cover the triangle, so a hit anywhere on it is reachable.
TEST(BvhEvh, PieceBoxesCoverTheirTriangle) {
  const Scene scene = sliver_scene();
  const auto refs = evh_presplit_refs(scene, evh_options(BvhBuilder::kBinned, 64));
  std::multimap<std::uint32_t, format::Box3f> boxes;
  for (const PrimRef& r : refs) boxes.emplace(r.prim, r.box);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (std::uint32_t i = 0; i < scene.triangles.size(); ++i) {
    const auto& t = scene.triangles[i];
    const Float3 a = scene.positions[t.v[0]], b = scene.positions[t.v[1]],
                 c = scene.positions[t.v[2]];
    for (int k = 0; k < 20; ++k) {
      double u = unit(rng), v = unit(rng);
      if (u + v > 1) u = 1 - u, v = 1 - v;
      const auto at = [&](float Float3::*m) {
        return float(a.*m + u * (double(b.*m) - a.*m) + v * (double(c.*m) - a.*m));
      };
      const Float3 p{at(&Float3::x), at(&Float3::y), at(&Float3::z)};
      const auto [lo, hi] = boxes.equal_range(i);
      const bool covered = std::any_of(lo, hi, [&](const auto& e) {
        const format::Box3f& box = e.second;
        return p.x >= box.min.x && p.x <= box.max.x && p.y >= box.min.y && p.y <= box.max.y &&
               p.z >= box.min.z && p.z <= box.max.z;
      });
      ASSERT_TRUE(covered) << "triangle " << i << " point " << k;
    }
  }
}

// A ray through each triangle's centroid along its normal, on a short interval around it: brute
// force finds that triangle, and so must the presplit BVH (closest and any hit); plus random rays.
TEST(BvhEvh, EveryTriangleIsStillFound) {
  const Scene scene = sliver_scene();
  std::vector<Ray> rays;
  for (const auto& t : scene.triangles) {
    const auto a = format::to_d(scene.positions[t.v[0]]), b = format::to_d(scene.positions[t.v[1]]),
               c = format::to_d(scene.positions[t.v[2]]);
    const auto n = format::normalize(format::cross(b - a, c - a));
    const auto centroid = (a + b + c) * (1.0 / 3.0);
    rays.push_back({format::to_f(centroid - n * 1e-3), 0.0f, format::to_f(n), 2e-3f});
  }
  const auto random_rays = box_rays(scene, 500);
  for (const auto builder : kBuilders) {
    SCOPED_TRACE(bvh_builder_name(builder));
    for (const std::uint32_t max_refs : {2u, 8u}) {
      const FlatBvh flat = build_bvh(scene, evh_options(builder, max_refs));
      const BvhView bvh(flat.nodes, flat.triangles, flat.prim_ids);
      expect_agrees_with_brute_force(scene, bvh, rays);
      expect_agrees_with_brute_force(scene, bvh, random_rays);
      std::size_t own = 0;
      for (std::uint32_t i = 0; i < rays.size(); ++i) {
        if (brute_force(scene, rays[i]).prim != i) continue;
        own += 1;
        EXPECT_EQ(bvh.intersect(rays[i]).prim, i);
      }
      EXPECT_GT(own, rays.size() * 9 / 10);
    }
  }
}

// The wide collapse merges binary leaves: a triangle whose pieces sit in two of them is still
// stored once per packet (lanes past the leaf's end repeat its last triangle).
TEST(BvhEvh, WideLeavesStoreATriangleOnce) {
  const Scene scene = sliver_scene();
  for (const std::uint32_t width : {4u, 8u}) {
    BvhBuildOptions o = evh_options(BvhBuilder::kBinned);
    o.leaf_triangles = false;
    const FlatBvh flat = build_bvh(scene, o);
    const FlatWideBvh wide = collapse_bvh(flat, width, scene.triangles.size(), false, &scene);
    EXPECT_LE(wide.stats.packet_fill, 1.0);
    std::vector<bool> present(scene.triangles.size(), false);
    std::size_t distinct = 0;
    for (std::size_t p = 0; p < wide.packets.size(); ++p) {
      const std::uint32_t* id = wide.packets[p].prim;
      for (std::uint32_t lane = 0; lane < format::kBvhPacketSize; ++lane) {
        present[id[lane]] = true;
        const bool repeated = std::find(id, id + lane, id[lane]) != id + lane;
        distinct += !repeated;
        if (repeated) {  // padding only: equal to the lane before, and so are the rest
          EXPECT_TRUE(std::all_of(id + lane - 1, id + format::kBvhPacketSize,
                                  [&](std::uint32_t x) { return x == id[lane]; }))
              << "packet " << p;
        }
      }
    }
    EXPECT_LT(distinct, flat.prim_ids.size());  // some binary leaves shared a triangle
    EXPECT_EQ(std::count(present.begin(), present.end(), true), std::ptrdiff_t(present.size()));
  }
}

TEST(BvhEvh, LowersTheSahCostOfSlivers) {
  const Scene scene = sliver_scene();
  for (const auto builder : kBuilders) {
    SCOPED_TRACE(bvh_builder_name(builder));
    BvhBuildOptions plain;
    plain.builder = builder;
    const double without = build_bvh(scene, plain).stats.sah_cost;
    const double with = build_bvh(scene, evh_options(builder)).stats.sah_cost;
    EXPECT_LT(with, 0.9 * without) << "with " << with << " without " << without;
  }
}

TEST(BvhEvh, SameOnAnyThreadCount) {
  const Scene scene = sliver_scene();
  for (const auto builder : kBuilders) {
    const FlatBvh one = build_bvh(scene, evh_options(builder, 8, 1));
    for (const unsigned threads : {2u, 8u}) {
      const FlatBvh other = build_bvh(scene, evh_options(builder, 8, threads));
      ASSERT_EQ(one.nodes.size(), other.nodes.size());
      EXPECT_EQ(std::memcmp(one.nodes.data(), other.nodes.data(),
                            one.nodes.size() * sizeof(format::BvhNode)),
                0);
      EXPECT_EQ(one.prim_ids, other.prim_ids);
    }
  }
  EXPECT_EQ(blob_with(scene, "bvh:presplit=evh", 1), blob_with(scene, "bvh:presplit=evh", 8));
}

TEST(BvhEvh, OptionParsesAndEntersTheCacheKey) {
  EXPECT_EQ(resolve_structure_request("bvh", {}).options.at("presplit"), "none");
  EXPECT_EQ(resolve_structure_request("bvh:presplit=evh", {}).options.at("presplit"),
            "evh=6.103515625e-05");
  EXPECT_EQ(
      resolve_structure_request("bvh", {{"--bvh-presplit", "evh=0.001"}}).options.at("presplit"),
      "evh=0.001");
  for (const char* bad : {"bvh:presplit=sah", "bvh:presplit=evh=2", "bvh:presplit=evh=x",
                          "bvh:evh-max-refs=0", "bvh:evh-max-refs=65"})
    EXPECT_THROW(resolve_structure_request(bad, {}), std::invalid_argument) << bad;
  EXPECT_THROW(resolve_structure_request("sbvh:presplit=evh", {}), std::invalid_argument);
  const auto key = [](const char* spec) {
    BuildOptions o;
    o.inputs = {"a.obj"};
    o.structures = {resolve_structure_request(spec, {})};
    return direct_key(o, std::vector<Hash128>{Hash128{}}, "fingerprint");
  };
  EXPECT_NE(key("bvh"), key("bvh:presplit=evh"));
  EXPECT_NE(key("bvh:presplit=evh"), key("bvh:presplit=evh=0.001"));
  EXPECT_NE(key("bvh:presplit=evh"), key("bvh:presplit=evh,evh-max-refs=4"));
}

// kiln dump --json reports the presplit and the SAH cost, lower than without it.
TEST(BvhEvh, DumpReportsThePresplitAndItsSahCost) {
  const Scene scene = sliver_scene();
  const auto dump = [&](const char* spec) {
    TempDir dir;
    const std::string path = dir.file("s.kiln");
    write_file(path, blob_with(scene, spec, 2));
    std::ostringstream out, err;
    EXPECT_EQ(run_dump(path, {true, false}, out, err), 0) << err.str();
    return nlohmann::json::parse(out.str())["manifest"]["structures"][0]["bvh"];
  };
  const auto evh = dump("bvh:presplit=evh,width=2");
  const auto plain = dump("bvh:width=2");
  EXPECT_EQ(evh["presplit"], "evh");
  EXPECT_EQ(plain["presplit"], "none");
  EXPECT_EQ(evh["evh_max_refs"], 8);
  EXPECT_GT(evh["presplit_references"].get<double>(), double(scene.triangles.size()));
  EXPECT_LT(evh["sah_cost"].get<double>(), plain["sah_cost"].get<double>());
}

}  // namespace
}  // namespace kiln
