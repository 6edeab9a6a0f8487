// The symmetry-aware sparse voxel DAG against the voxel DAG of the same voxels (the reference:
// an independent structure): the same voxel set at several resolutions, the same ray hits, the
// DAG's node counts and bytes; mirrors against coordinate flips; symmetric merges where a
// mirrored copy exists; deterministic words; forged words refused; the command line.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <random>

#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/compiler/ssvdag_builder.hpp"
#include "kiln/compiler/voxel_dag_builder.hpp"
#include "kiln/compiler/voxelizer.hpp"
#include "kiln/formats/ssvdag.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/ssvdag.hpp"
#include "kiln/tools/ray_generator.hpp"
#include "ray_fixtures.hpp"
#include "test_support.hpp"
#include "voxel_fixtures.hpp"

namespace kiln {
namespace {

using format::Float3;
using namespace kiln::test;

// The surface voxels and both structures over them.
struct Both {
  BuiltDag dag;
  FlatSsvdag ssvdag;
  std::vector<std::uint64_t> firsts;
  SsvdagView view() const {
    return SsvdagView(ssvdag.words, ssvdag.leaves, frame_of(dag.voxels.grid), firsts,
                      ssvdag.root_mirror);
  }
};

Both build_both(const Scene& scene, std::uint32_t resolution,
                const SsvdagPointerReach& reach = {}) {
  Both b;
  b.dag = build_dag(scene, resolution);
  b.ssvdag = build_ssvdag(b.dag.voxels.codes, resolution, 2, reach);
  b.firsts = ssvdag_level_first_words(b.ssvdag);
  return b;
}

// Pointer reaches far below the format's, so that SSVDAGs of 64^3-256^3 take every kind of
// pointer: absolute, relative and wide into interior levels, narrow and wide into the leaves.
constexpr SsvdagPointerReach kShortReach{4, 8, 16};

// The pointers of an SSVDAG by kind, read from its words (not from the builder's statistics).
struct PointerKinds {
  std::uint64_t absolute = 0, relative = 0, wide = 0, leaf_narrow = 0, leaf_wide = 0;
};

PointerKinds pointer_kinds(const FlatSsvdag& s) {
  PointerKinds k;
  const auto firsts = ssvdag_level_first_words(s);
  const std::size_t interior = firsts.size();
  for (std::size_t l = 0; l < interior; ++l) {
    const std::uint64_t end = l + 1 < interior ? firsts[l + 1] : s.words.size();
    for (std::uint64_t w = firsts[l]; w < end;) {
      const std::uint32_t mask = s.words[w] & 0xFFu, wide = s.words[w] >> 8;
      std::uint64_t at = w + 1;
      for (std::uint32_t c = 0; c < 8; ++c) {
        if ((mask >> c & 1) == 0) continue;
        const bool is_wide = wide >> c & 1, to_leaves = l + 1 == interior;
        if (to_leaves)
          ++(is_wide ? k.leaf_wide : k.leaf_narrow);
        else if (is_wide)
          ++k.wide;
        else
          ++(s.words[at] >> 3 >= format::kSsvdagAbsoluteOffsets ? k.relative : k.absolute);
        at += is_wide ? 2 : 1;
      }
      w = at;
    }
  }
  return k;
}

void expect_every_pointer_kind(const FlatSsvdag& s, std::uint32_t resolution) {
  const PointerKinds k = pointer_kinds(s);
  EXPECT_GT(k.absolute, 0u) << resolution;
  EXPECT_GT(k.relative, 0u) << resolution;
  EXPECT_GT(k.wide, 0u) << resolution;
  EXPECT_GT(k.leaf_narrow, 0u) << resolution;
  EXPECT_GT(k.leaf_wide, 0u) << resolution;
  std::uint64_t relative = 0, wide = 0;
  for (const auto& l : s.level_stats) relative += l.relative_pointers, wide += l.wide_pointers;
  EXPECT_EQ(relative, k.relative);
  EXPECT_EQ(wide, k.wide + k.leaf_wide);
}

Scene mesh_or_icosphere(const char* relative) {
  if (corpus_present()) return import_scene({mesh_path(relative)}, 2);
  return icosphere(3);
}

// Primary rays at the mesh and random rays from inside the bounds, some along the axes.
std::vector<Ray> rays_for(const Scene& scene, std::size_t count, std::uint32_t seed) {
  const FlatBvh flat = build_bvh(scene, {});
  const BvhView bvh(flat.nodes, flat.triangles, flat.prim_ids);
  std::vector<Ray> rays =
      generate_rays({bvh, scene.positions, scene.triangles, scene.bounds.min, scene.bounds.max},
                    RayKind::kPrimary, count / 2, seed, 2);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(0, 1), sym(-1, 1);
  const Float3 lo = scene.bounds.min, hi = scene.bounds.max;
  while (rays.size() < count) {
    const Float3 o{lo.x + (hi.x - lo.x) * unit(rng), lo.y + (hi.y - lo.y) * unit(rng),
                   lo.z + (hi.z - lo.z) * unit(rng)};
    Float3 d{sym(rng), sym(rng), sym(rng)};
    if (rays.size() % 10 == 0) {
      const int axis = int(rays.size() / 10 % 3);
      d = {axis == 0 ? -1.0f : 0.0f, axis == 1 ? 1.0f : 0.0f, axis == 2 ? -1.0f : 0.0f};
    }
    rays.push_back({o, 0.0f, d, INFINITY});
  }
  return rays;
}

TEST(Ssvdag, MirrorsAreCoordinateFlips) {
  std::mt19937_64 rng(5);
  for (int trial = 0; trial < 50; ++trial) {
    const std::uint64_t leaf = rng();
    for (std::uint32_t t = 0; t < 8; ++t) {
      const std::uint64_t m = format::ssvdag_mirror_leaf(leaf, t);
      EXPECT_EQ(format::ssvdag_mirror_leaf(m, t), leaf);
      for (std::uint32_t x = 0; x < 4; ++x)
        for (std::uint32_t y = 0; y < 4; ++y)
          for (std::uint32_t z = 0; z < 4; ++z) {
            const auto fx = t & 1 ? 3 - x : x, fy = t & 2 ? 3 - y : y, fz = t & 4 ? 3 - z : z;
            ASSERT_EQ(m >> format::morton_code(fx, fy, fz) & 1,
                      leaf >> format::morton_code(x, y, z) & 1);
          }
    }
    const auto mask = std::uint32_t(rng() & 0xFF);
    for (std::uint32_t t = 0; t < 8; ++t)
      for (std::uint32_t o = 0; o < 8; ++o)
        EXPECT_EQ(format::ssvdag_mirror_mask(mask, t) >> (o ^ t) & 1, mask >> o & 1);
  }
}

TEST(Ssvdag, ExpandsToTheDagVoxelSetAtSeveralResolutions) {
  const Scene scene = mesh_or_icosphere("stanford/stanford-bunny.obj.zst");
  for (const std::uint32_t resolution : {8u, 16u, 32u, 64u, 128u, 256u, 129u, 257u}) {
    // 129 and 257: 128 and 256 with short pointer reaches (every kind of pointer).
    const bool short_reach = resolution % 2 == 1;
    const Both b = short_reach ? build_both(scene, resolution - 1, kShortReach)
                               : build_both(scene, resolution);
    if (short_reach) expect_every_pointer_kind(b.ssvdag, resolution);
    const auto& dag = b.dag.dag;
    EXPECT_EQ(expand_ssvdag(b.ssvdag), expand_voxel_dag(dag.words, dag.levels)) << resolution;
    EXPECT_EQ(expand_ssvdag(b.ssvdag), b.dag.voxels.codes) << resolution;
    // The DAG the SSVDAG counts beside itself is the DAG builder's, node for node.
    EXPECT_EQ(b.ssvdag.dag_bytes, dag.dag_bytes);
    EXPECT_EQ(b.ssvdag.svo_bytes, dag.svo_bytes);
    for (std::size_t l = 0; l < dag.level_stats.size(); ++l) {
      EXPECT_EQ(b.ssvdag.level_stats[l].dag_nodes, dag.level_stats[l].dag_nodes);
      EXPECT_LE(b.ssvdag.level_stats[l].ssvdag_nodes, dag.level_stats[l].dag_nodes);
    }
    EXPECT_EQ(b.view().count_voxels(), b.dag.voxels.codes.size());
    if (resolution >= 64 && !short_reach) {
      EXPECT_LT(b.ssvdag.ssvdag_bytes, dag.dag_bytes) << resolution;
    }
  }
}

TEST(Ssvdag, OccupancyEqualsTheDagEverywhere) {
  const Scene scene = mesh_or_icosphere("classic/teapot.obj");
  for (const std::uint32_t resolution : {16u, 64u, 65u}) {
    // 65: 64 with short pointer reaches (every kind of pointer).
    const std::uint32_t n = resolution & ~1u;
    const Both b = n == resolution ? build_both(scene, n) : build_both(scene, n, kShortReach);
    if (n != resolution) expect_every_pointer_kind(b.ssvdag, resolution);
    const VoxelDagView dag = b.dag.view();
    const SsvdagView ssvdag = b.view();
    std::size_t set = 0;
    for (std::uint32_t z = 0; z < n; ++z)
      for (std::uint32_t y = 0; y < n; ++y)
        for (std::uint32_t x = 0; x < n; ++x) {
          ASSERT_EQ(ssvdag.occupied(x, y, z), dag.occupied(x, y, z)) << x << " " << y << " " << z;
          set += dag.occupied(x, y, z);
        }
    EXPECT_EQ(set, b.dag.voxels.codes.size());
    EXPECT_FALSE(ssvdag.occupied(n, 0, 0));
  }
}

TEST(Ssvdag, SolidVoxelsExpandToTheDagSet) {
  const Scene scene = icosphere(3);
  const Voxels voxels = voxelize_surface(scene, {64, false, 2});
  const VoxelLeaves solid = solid_leaves(scene, voxels.grid, voxels.codes, 2);
  const FlatVoxelDag dag = build_voxel_dag(solid, 64);
  const FlatSsvdag ssvdag = build_ssvdag(solid, 64, 2);
  EXPECT_GT(solid.voxel_count, voxels.codes.size());
  EXPECT_EQ(expand_ssvdag(ssvdag), expand_voxel_dag(dag.words, dag.levels));
  EXPECT_EQ(ssvdag.dag_bytes, dag.dag_bytes);
}

TEST(Ssvdag, CastsEqualTheDagHits) {
  const Scene scene = mesh_or_icosphere("classic/teapot.obj");
  const auto rays = rays_for(scene, 4000, 3);
  for (const std::uint32_t resolution : {32u, 128u, 129u}) {
    // 129: 128 with short pointer reaches (every kind of pointer).
    const std::uint32_t n = resolution & ~1u;
    const Both b = n == resolution ? build_both(scene, n) : build_both(scene, n, kShortReach);
    if (n != resolution) expect_every_pointer_kind(b.ssvdag, resolution);
    const VoxelDagView dag = b.dag.view();
    const SsvdagView ssvdag = b.view();
    std::size_t hits = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
      const VoxelHit expected = dag.intersect_any(rays[i]);
      Cost cost;
      const VoxelHit got = ssvdag.intersect_counting(rays[i], cost);
      ASSERT_EQ(got.hit(), expected.hit()) << "ray " << i;
      EXPECT_EQ(ssvdag.occluded(rays[i]), expected.hit());
      if (!expected.hit()) continue;
      ++hits;
      ASSERT_EQ(got.x, expected.x) << "ray " << i;
      ASSERT_EQ(got.y, expected.y);
      ASSERT_EQ(got.z, expected.z);
      // The same steps on the same boxes: the same float t and entered face.
      ASSERT_EQ(got.t, expected.t);
      for (int a = 0; a < 3; ++a) ASSERT_EQ(got.face_normal[a], expected.face_normal[a]);
    }
    EXPECT_GT(hits, rays.size() / 4) << resolution;
  }
}

// At 131,072^3 (17 levels) the SSVDAG reduced from the out-of-core DAG of the slivers casts as
// the DAG does: rays at points of the slivers and down voxel columns hit the same voxel at the
// same t, and occupancy agrees around each hit.
TEST(Ssvdag, CastsEqualTheDagAt131072) {
  const Scene scene = slivers();
  const std::uint32_t n = format::kVoxelMaxResolution;
  const VoxelGrid grid = fit_voxel_grid(scene.bounds, n);
  OutOfCoreDagOptions options;
  options.cube_side = 4096;
  options.threads = 2;
  const FlatVoxelDag flat = build_voxel_dag_out_of_core(scene, grid, options);
  const VoxelDagView dag(flat.words, frame_of(grid), level_first_words(flat), flat.leaf_first_word,
                         {}, {});
  const FlatSsvdag s = build_ssvdag(flat, 2);
  const SsvdagView ssvdag(s.words, s.leaves, frame_of(grid), ssvdag_level_first_words(s),
                          s.root_mirror);
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> unit(0, 1), sym(-1, 1);
  std::size_t hits = 0;
  for (int i = 0; i < 3000; ++i) {
    // A point on a random sliver, seen from a random origin around the unit cube.
    const auto& t = scene.triangles[i % scene.triangles.size()];
    float a = unit(rng), b = unit(rng);
    if (a + b > 1) a = 1 - a, b = 1 - b;
    const format::Double3 p0 = format::to_d(scene.positions[t.v[0]]),
                          p1 = format::to_d(scene.positions[t.v[1]]),
                          p2 = format::to_d(scene.positions[t.v[2]]);
    const format::Double3 target = p0 + (p1 - p0) * a + (p2 - p0) * b;
    const Float3 origin{0.5f + 1.5f * sym(rng), 0.5f + 1.5f * sym(rng), 0.5f + 1.5f * sym(rng)};
    const Ray ray{origin, 0.0f, format::to_f(target - format::to_d(origin)), INFINITY};
    const VoxelHit expected = dag.intersect(ray), got = ssvdag.intersect(ray);
    ASSERT_EQ(got.hit(), expected.hit()) << "ray " << i;
    if (!expected.hit()) continue;
    ++hits;
    ASSERT_EQ(got.x, expected.x) << "ray " << i;
    ASSERT_EQ(got.y, expected.y) << "ray " << i;
    ASSERT_EQ(got.z, expected.z) << "ray " << i;
    ASSERT_EQ(got.t, expected.t) << "ray " << i;
    for (std::uint32_t dz = 0; dz < 3; ++dz) {
      const std::uint32_t z = std::min(n - 1, expected.z + dz);
      ASSERT_EQ(ssvdag.occupied(expected.x, expected.y, z),
                dag.occupied(expected.x, expected.y, z));
    }
  }
  EXPECT_GT(hits, 1000u);
}

// Random voxels in one octant of the grid and their mirror image in another: the DAG keeps both
// subtrees, the SSVDAG one with a mirror pointer, for each of the seven mirrors.
TEST(Ssvdag, MergesMirroredSubtrees) {
  std::mt19937 rng(9);
  for (std::uint32_t t = 1; t < 8; ++t) {
    std::vector<std::uint64_t> codes;
    for (int i = 0; i < 300; ++i) {
      const std::uint32_t x = rng() % 16, y = rng() % 16, z = rng() % 16;
      codes.push_back(format::morton_code(x, y, z));
      codes.push_back(
          format::morton_code(t & 1 ? 31 - x : x, t & 2 ? 31 - y : y, t & 4 ? 31 - z : z));
    }
    std::sort(codes.begin(), codes.end());
    codes.erase(std::unique(codes.begin(), codes.end()), codes.end());
    const FlatSsvdag s = build_ssvdag(codes, 32, 2);
    EXPECT_EQ(expand_ssvdag(s), codes) << t;
    EXPECT_EQ(s.level_stats[1].dag_nodes, 2u) << t;
    EXPECT_EQ(s.level_stats[1].ssvdag_nodes, 1u) << t;
    EXPECT_GE(s.symmetry_merges, 1u);
    EXPECT_LT(s.ssvdag_bytes, s.dag_bytes);
  }
}

TEST(Ssvdag, WordsIdenticalAcrossThreadCounts) {
  const Scene scene = mesh_or_icosphere("classic/teapot.obj");
  const Voxels voxels = voxelize_surface(scene, {128, false, 2});
  const FlatSsvdag one = build_ssvdag(voxels.codes, 128, 1);
  for (const unsigned threads : {2u, 8u}) {
    const FlatSsvdag other = build_ssvdag(voxels.codes, 128, threads);
    EXPECT_EQ(other.words, one.words);
    EXPECT_EQ(other.leaves, one.leaves);
    EXPECT_EQ(other.root_mirror, one.root_mirror);
  }
  EXPECT_THROW(build_ssvdag(std::vector<std::uint64_t>{}, 128, 1), std::invalid_argument);
  EXPECT_THROW(build_ssvdag(std::vector<std::uint64_t>{std::uint64_t(1) << 24}, 128, 1),
               std::invalid_argument);
}

TEST(Ssvdag, ForgedWordsAreRefusedOrSafe) {
  const Both b = build_both(icosphere(2), 64);
  const VoxelGridFrame frame = frame_of(b.dag.voxels.grid);
  // The view keeps spans: the vectors outlive it (a temporary lives to the end of the statement).
  auto open = [&](const std::vector<std::uint16_t>& words, const std::vector<std::uint64_t>& firsts,
                  std::uint32_t root_mirror) {
    return SsvdagView(words, b.ssvdag.leaves, frame, firsts, root_mirror);
  };
  const auto& w = b.ssvdag.words;
  auto patched = [&](std::size_t at, std::uint16_t value) {
    auto copy = w;
    copy[at] = value;
    return copy;
  };
  EXPECT_NO_THROW(open(w, b.firsts, b.ssvdag.root_mirror));
  EXPECT_THROW(open(w, b.firsts, 8), BlobError);
  EXPECT_THROW(open(patched(0, 0), b.firsts, 0), BlobError);  // empty root
  ASSERT_GT(std::popcount(w[0] & 0xFFu), 1);
  // A wide bit for an octant the child mask lacks.
  EXPECT_THROW(open(patched(0, std::uint16_t((w[0] & 0xFE) | 0x100)), b.firsts, 0),
               BlobError);  // a wide bit outside the child mask
  EXPECT_THROW(open(patched(1, 0xFFF8), b.firsts, 0), BlobError);  // past the next level
  auto firsts = b.firsts;
  firsts[1] += 1;  // levels out of step with the nodes
  EXPECT_THROW(open(w, firsts, 0), BlobError);
  firsts.pop_back();
  EXPECT_THROW(open(w, firsts, 0), BlobError);
  // Any word changed: refused at open, or every query stays in range (ASan checks).
  const auto rays = rays_for(icosphere(2), 64, 1);
  std::mt19937 rng(2);
  for (int trial = 0; trial < 300; ++trial) {
    auto forged = patched(rng() % w.size(), std::uint16_t(rng()));
    try {
      const SsvdagView view = open(forged, b.firsts, rng() % 8);
      for (const Ray& r : rays) view.intersect(r);
      view.count_voxels();
      for (std::uint32_t i = 0; i < 512; ++i) view.occupied(i % 64, i / 8 % 64, i * 7 % 64);
    } catch (const BlobError&) {
    }
  }
}

// Relative pointers at open: one in a node without a wide pointer (no base), and one whose
// offset falls before its level, are refused; any word of an SSVDAG with every kind of pointer
// changed is refused or stays in range.
TEST(Ssvdag, ForgedRelativePointersAreRefused) {
  const Both b = build_both(icosphere(3), 128, kShortReach);
  expect_every_pointer_kind(b.ssvdag, 129);
  const VoxelGridFrame frame = frame_of(b.dag.voxels.grid);
  auto open = [&](const std::vector<std::uint16_t>& words) {
    return SsvdagView(words, b.ssvdag.leaves, frame, b.firsts, b.ssvdag.root_mirror);
  };
  const auto& w = b.ssvdag.words;
  EXPECT_NO_THROW(open(w));
  bool no_base = false, before_level = false;
  // Nodes of the levels whose pointers go to interior levels.
  for (std::uint64_t at = 0; at < b.firsts.back() && !(no_base && before_level);) {
    const std::uint32_t mask = w[at] & 0xFFu, wide = w[at] >> 8;
    const std::uint64_t size = 1 + std::popcount(mask) + std::popcount(wide);
    // The word of child c's pointer.
    auto word_of = [&](std::uint32_t c) {
      const std::uint32_t below = (1u << c) - 1;
      return at + 1 + std::popcount(mask & below) + std::popcount(wide & below);
    };
    auto forged = w;
    const std::uint32_t f = std::countr_zero(wide);  // 32 without a wide pointer
    const std::uint32_t later = f < 8 ? mask & ~wide & ~((2u << f) - 1) : 0;
    if (wide == 0 && !no_base) {
      const std::uint64_t p = word_of(std::countr_zero(mask));
      forged[p] = std::uint16_t(format::kSsvdagAbsoluteOffsets << 3 | (w[p] & 7u));
      EXPECT_THROW(open(forged), BlobError) << "relative pointer without a wide one at " << p;
      no_base = true;
    } else if (later != 0 && !before_level) {
      // A narrow pointer after the first wide one, set to 2048 words before that one's offset.
      const std::uint64_t base_at = word_of(f);
      const std::uint32_t base = (w[base_at] | std::uint32_t(w[base_at + 1]) << 16) >> 3;
      if (base < format::kSsvdagRelativeReach) {
        const std::uint64_t p = word_of(std::countr_zero(later));
        forged[p] = std::uint16_t(format::kSsvdagAbsoluteOffsets << 3 | (w[p] & 7u));
        EXPECT_THROW(open(forged), BlobError) << "relative pointer before its level at " << p;
        before_level = true;
      }
    }
    at += size;
  }
  EXPECT_TRUE(no_base);
  EXPECT_TRUE(before_level);
  const auto rays = rays_for(icosphere(3), 64, 4);
  std::mt19937 rng(5);
  for (int trial = 0; trial < 300; ++trial) {
    auto forged = w;
    forged[rng() % w.size()] = std::uint16_t(rng());
    try {
      const SsvdagView view = open(forged);
      for (const Ray& r : rays) view.intersect(r);
      view.count_voxels();
      for (std::uint32_t i = 0; i < 512; ++i) view.occupied(i % 128, i / 8 % 128, i * 7 % 128);
    } catch (const BlobError&) {
    }
  }
}

TEST(Ssvdag, CommandLineBuildDumpVerifyTrace) {
  KILN_REQUIRE_CORPUS();
  TempDir dir;
  const std::string mesh = mesh_path("classic/teapot.obj");
  const std::string blob = dir.file("s.kiln"), rays = dir.file("r.bin"), hits = dir.file("h.bin");
  ASSERT_EQ(
      run_kiln("build " + quoted(mesh) + " --accel ssvdag --resolution 128 -o " + quoted(blob))
          .exit_code,
      0);
  const auto dump = run_kiln("dump " + quoted(blob));
  EXPECT_NE(dump.out.find("merged by symmetry"), std::string::npos) << dump.out;
  EXPECT_NE(dump.out.find("SSVDAG/DAG"), std::string::npos) << dump.out;
  const auto json = run_kiln("dump --json " + quoted(blob));
  EXPECT_NE(json.out.find("\"ssvdag_dag_ratio\""), std::string::npos);
  EXPECT_EQ(run_kiln("verify " + quoted(blob)).exit_code, 0);
  ASSERT_EQ(run_kiln("rays " + quoted(mesh) + " --count 2000 -o " + quoted(rays)).exit_code, 0);
  ASSERT_EQ(run_kiln("trace " + quoted(blob) + " --accel ssvdag --rays " + quoted(rays) +
                     " --out " + quoted(hits))
                .exit_code,
            0);
  const auto bytes = read_file(hits), ray_bytes = read_file(rays);
  ASSERT_EQ(bytes.size(), 2000 * sizeof(VoxelHitRecord));
  const Both b = build_both(import_scene({mesh}, 2), 128);
  std::size_t wrong = 0;
  for (std::size_t i = 0; i < 2000; ++i) {
    Ray ray;
    VoxelHitRecord from_file;
    std::memcpy(&ray, ray_bytes.data() + i * sizeof ray, sizeof ray);
    std::memcpy(&from_file, bytes.data() + i * sizeof from_file, sizeof from_file);
    VoxelHit expected = b.dag.view().intersect_any(ray);  // no normals: the entered face
    const VoxelHitRecord record = to_record(expected);
    wrong += std::memcmp(&from_file, &record, sizeof record) != 0;
  }
  EXPECT_EQ(wrong, 0u);
}

}  // namespace
}  // namespace kiln
