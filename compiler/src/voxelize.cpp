// Surface voxelization brick by brick: triangles are binned to the bricks (128^3 voxels, in
// Morton order) their plane's slab reaches, in parallel over fixed ranges of triangles whose
// entries are joined per brick in range order (so each bin lists its triangles in the given
// order whatever the thread count); each brick walks its triangles column by column along
// each triangle's dominant axis, where every separating-axis test is an interval of the column
// (voxelize_columns.hpp: closed form, exact via margins; small triangles on AVX2 / AVX-512 CPUs:
// every voxel of their range at once, voxelize_window.hpp), and sets bits in a per-thread bit array
// laid out in Morton order, whose words are the 4x4x4 leaves. Leaves come out in order without
// per-voxel codes or a sort; concatenating bricks in Morton order gives the global order, and
// every brick is a pure function of its triangles, so any thread count gives the same bytes.
#if defined(__linux__)
#include <sys/mman.h>
#endif

#include <algorithm>
#include <bit>
#include <cmath>
#include <stdexcept>
#include <string>

#include "kiln/compiler/voxelizer.hpp"
#include "kiln/formats/voxel_grid.hpp"
#include "kiln/runtime/parallel.hpp"
#include "voxelize_columns.hpp"

namespace kiln {

namespace {

using voxelize_detail::candidate_range;
using voxelize_detail::is_empty;
using voxelize_detail::TriangleColumns;
using voxelize_detail::VoxelRange;

constexpr std::uint32_t kBrickSide = 128;

// A point in grid units (voxel (x, y, z) is the box [x, x+1] x ...): to_grid's arithmetic.
format::Double3 grid_point(const VoxelGrid& grid, const format::Float3& p) {
  return {(double(p.x) - grid.origin[0]) / grid.voxel_size,
          (double(p.y) - grid.origin[1]) / grid.voxel_size,
          (double(p.z) - grid.origin[2]) / grid.voxel_size};
}

GridTriangle grid_triangle(const Scene& scene, const VoxelGrid& grid, std::uint32_t i) {
  const auto& tri = scene.triangles[i];
  return to_grid(grid, scene.positions[tri.v[0]], scene.positions[tri.v[1]],
                 scene.positions[tri.v[2]]);
}

// The scene's triangles in grid units. When the triangles to voxelize reference a good share of
// the vertices, every vertex is converted once (three divisions per vertex instead of nine per
// triangle, each triangle being read twice: binning and walk; the same arithmetic, so the same
// doubles); otherwise each triangle converts its corners.
class GridMesh {
 public:
  GridMesh(const Scene& scene, const VoxelGrid& grid, std::size_t triangle_count, unsigned threads)
      : scene(scene), grid_(grid) {
    if (2 * triangle_count < scene.positions.size()) return;
    corners_.resize(scene.positions.size());
    parallel_for_batched(corners_.size(), std::size_t{1} << 15, threads, [&](std::size_t k) {
      corners_[k] = grid_point(grid, scene.positions[k]);
    });
  }
  GridTriangle triangle(std::uint32_t i) const {
    if (corners_.empty()) return grid_triangle(scene, grid_, i);
    const auto& tri = scene.triangles[i];
    return {{corners_[tri.v[0]], corners_[tri.v[1]], corners_[tri.v[2]]}};
  }
  // Hints that triangle(i) comes soon: its vertex indices, or (once those are cached) its
  // corners. The triangles of a brick are scattered over the vertex array (MBs).
  void prefetch_indices(std::uint32_t i) const { __builtin_prefetch(&scene.triangles[i]); }
  void prefetch_corners(std::uint32_t i) const {
    if (corners_.empty()) return;
    const auto& tri = scene.triangles[i];
    for (int k = 0; k < 3; ++k) __builtin_prefetch(&corners_[tri.v[k]]);
  }
  const Scene& scene;

 private:
  const VoxelGrid& grid_;
  std::vector<format::Double3> corners_;
};

// The cube as an inclusive voxel range.
VoxelRange range_of(const VoxelCube& cube) {
  VoxelRange r;
  for (int a = 0; a < 3; ++a)
    r.lo[a] = cube.origin[a], r.hi[a] = std::int64_t(cube.origin[a]) + cube.side - 1;
  return r;
}

// Morton bits of 0..127 (format::spread_bits: bit b to bit 3b), one table for the three axes
// (shifted by 0, 1, 2); constants, so that no call checks a static's initialization.
struct SpreadTable {
  std::uint32_t bits[kBrickSide];
};
constexpr SpreadTable make_spread_table() {
  SpreadTable t{};
  for (std::uint32_t i = 0; i < kBrickSide; ++i)
    for (std::uint32_t b = 0; b < 7; ++b) t.bits[i] |= (i >> b & 1u) << (3 * b);
  return t;
}
constexpr SpreadTable kSpreadTable = make_spread_table();
static_assert(kBrickSide == 128, "seven bits per coordinate");

// Bits of the voxels k0..k1 (0..3) along axis a inside a 4x4x4 leaf, at u = v = 0.
struct RunTable {
  std::uint64_t masks[3][4][4] = {};
};
constexpr RunTable make_run_table() {
  RunTable t{};
  for (int a = 0; a < 3; ++a)
    for (std::uint32_t k0 = 0; k0 < 4; ++k0)
      for (std::uint32_t k1 = k0; k1 < 4; ++k1)
        for (std::uint32_t k = k0; k <= k1; ++k)
          t.masks[a][k0][k1] |= std::uint64_t{1} << (kSpreadTable.bits[k] << a);
  return t;
}
constexpr RunTable kRunTable = make_run_table();

// A brick's voxels as bits in Morton order: word w is the 4x4x4 leaf whose local key is w, so the
// leaves come out in order with no per-voxel codes and no sort. A summary bit per word lists the
// non-empty leaves without scanning the whole brick (mostly empty on a surface), and clearing
// touches only those, so one array per thread serves every brick.
class BrickBits {
 public:
  void prepare(std::uint32_t side) {
    const std::size_t words = std::size_t(side) * side * side / 64;
    if (words_.size() != words) words_.assign(words, 0), summary_.assign((words + 63) / 64, 0);
  }
  static std::uint32_t index(std::uint32_t x, std::uint32_t y, std::uint32_t z) {
    const std::uint32_t* s = kSpreadTable.bits;
    return s[x] | s[y] << 1 | s[z] << 2;
  }
  void set(std::uint32_t i) {
    words_[i >> 6] |= std::uint64_t{1} << (i & 63);
    summary_[i >> 12] |= std::uint64_t{1} << ((i >> 6) & 63);
  }
  // The leaf whose first voxel is p (local) gets `mask` (Morton order within the leaf; may be
  // empty).
  void set_leaf(const std::uint32_t p[3], std::uint64_t mask) {
    const std::uint32_t w = index(p[0], p[1], p[2]) >> 6;
    words_[w] |= mask;
    summary_[w >> 6] |= std::uint64_t(mask != 0) << (w & 63);
  }
  // Voxels (x, y, z) with coordinate `a` from p[a] to last (local), a 4x4x4 leaf at a time: the
  // run's bits within a leaf come from a table, shifted to the column's place.
  void set_run(std::uint32_t p[3], int a, std::uint32_t last) {
    for (std::uint32_t first = p[a]; first <= last;) {
      const std::uint32_t end = std::min(last, first | 3);
      p[a] = first & ~3u;
      const std::uint32_t i = index(p[0], p[1], p[2]);
      words_[i >> 6] |= kRunTable.masks[a][first & 3][end & 3] << (i & 63);
      summary_[i >> 12] |= std::uint64_t{1} << ((i >> 6) & 63);
      first = end + 1;
    }
  }
  std::uint64_t word(std::size_t w) const { return words_[w]; }
  // The number of non-empty words.
  std::size_t leaf_count() const {
    std::size_t n = 0;
    for (const std::uint64_t s : summary_) n += std::size_t(std::popcount(s));
    return n;
  }
  // f(w, mask) for every non-empty word, ascending.
  template <class F>
  void for_each_leaf(F f) const {
    for (std::size_t s = 0; s < summary_.size(); ++s)
      for (std::uint64_t bits = summary_[s]; bits != 0; bits &= bits - 1) {
        const std::size_t w = s * 64 + std::size_t(std::countr_zero(bits));
        f(w, words_[w]);
      }
  }
  void clear() {
    for_each_leaf([&](std::size_t w, std::uint64_t) { words_[w] = 0; });
    std::fill(summary_.begin(), summary_.end(), 0);
  }

 private:
  std::vector<std::uint64_t> words_, summary_;
};

// This thread's bit array, empty, for a brick of `side`; cleared again when the lease ends, even
// by an exception, so the next brick on this thread starts empty.
class BitsLease {
 public:
  explicit BitsLease(std::uint32_t side) : bits_(storage()) { bits_.prepare(side); }
  ~BitsLease() { bits_.clear(); }
  BitsLease(const BitsLease&) = delete;
  BitsLease& operator=(const BitsLease&) = delete;
  BrickBits& bits() { return bits_; }

 private:
  static BrickBits& storage() {
    thread_local BrickBits bits;
    return bits;
  }
  BrickBits& bits_;
};

struct Brick {
  VoxelRange clip;
  std::uint64_t first_key = 0;  // global leaf key of the brick's first 4x4x4 block
};

// Brick `b` (Morton index within `cube`) of side `brick`.
Brick brick_of(const VoxelCube& cube, std::uint32_t brick, std::size_t b) {
  Brick out;
  const std::uint32_t local[3] = {format::compact_bits(b), format::compact_bits(b >> 1),
                                  format::compact_bits(b >> 2)};
  for (int a = 0; a < 3; ++a)
    out.clip.lo[a] = std::int64_t(cube.origin[a]) + std::int64_t(local[a]) * brick,
    out.clip.hi[a] = out.clip.lo[a] + brick - 1;
  const int shift = 3 * std::countr_zero(brick);
  out.first_key = (format::morton_code(cube.origin[0], cube.origin[1], cube.origin[2]) |
                   std::uint64_t(b) << shift) >>
                  6;
  return out;
}

// Calls on_run(triangle, local p, a, last) for runs of voxels along axis a (brick-local, p[a] to
// last), on_leaf(triangle, local p, bits) for the voxels of the 4x4x4 leaf whose first voxel is
// p (bits in Morton order within the leaf), and on_voxel(triangle, x, y, z) for single voxels
// (brick-local), covering every voxel of `brick` each triangle touches once, triangle by triangle
// in the given order.
template <class OnRun, class OnLeaf, class OnVoxel>
void rasterize(const GridMesh& mesh, std::span<const std::uint32_t> triangles, const Brick& brick,
               OnRun on_run, OnLeaf on_leaf, OnVoxel on_voxel) {
  TriangleColumns columns(voxelize_detail::selected_window_kernel());
  const std::int64_t* o = brick.clip.lo;
  for (std::size_t k = 0; k < triangles.size(); ++k) {
    if (k + 8 < triangles.size()) mesh.prefetch_indices(triangles[k + 8]);
    if (k + 4 < triangles.size()) mesh.prefetch_corners(triangles[k + 4]);
    const std::uint32_t i = triangles[k];
    if (!columns.setup(mesh.triangle(i))) continue;
    columns.walk(
        brick.clip,
        [&](const std::int64_t* c, int a, std::int64_t last) {
          std::uint32_t p[3] = {std::uint32_t(c[0] - o[0]), std::uint32_t(c[1] - o[1]),
                                std::uint32_t(c[2] - o[2])};
          on_run(i, p, a, std::uint32_t(last - o[a]));
        },
        [&](const std::int64_t* g, std::uint64_t bits) {
          const std::uint32_t p[3] = {std::uint32_t(g[0] - o[0]), std::uint32_t(g[1] - o[1]),
                                      std::uint32_t(g[2] - o[2])};
          on_leaf(i, p, bits);
        },
        [&](std::uint32_t x, std::uint32_t y, std::uint32_t z) {
          on_voxel(i, std::uint32_t(x - o[0]), std::uint32_t(y - o[1]), std::uint32_t(z - o[2]));
        });
  }
}

// rasterize with one callback per voxel (brick-local Morton index).
template <class OnVoxel>
void rasterize_voxels(const GridMesh& mesh, std::span<const std::uint32_t> triangles,
                      const Brick& brick, OnVoxel on_voxel) {
  rasterize(
      mesh, triangles, brick,
      [&](std::uint32_t t, std::uint32_t* p, int a, std::uint32_t last) {
        for (std::uint32_t k = p[a]; k <= last; ++k) {
          p[a] = k;
          on_voxel(t, BrickBits::index(p[0], p[1], p[2]));
        }
      },
      [&](std::uint32_t t, const std::uint32_t* p, std::uint64_t bits) {
        const std::uint32_t first = BrickBits::index(p[0], p[1], p[2]);
        for (; bits != 0; bits &= bits - 1)
          on_voxel(t, first + std::uint32_t(std::countr_zero(bits)));
      },
      [&](std::uint32_t t, std::uint32_t x, std::uint32_t y, std::uint32_t z) {
        on_voxel(t, BrickBits::index(x, y, z));
      });
}

// Sets the bits of every voxel `triangles` touch in `brick`.
void rasterize_bits(const GridMesh& mesh, std::span<const std::uint32_t> triangles,
                    const Brick& brick, BrickBits& bits) {
  rasterize(
      mesh, triangles, brick,
      [&](std::uint32_t, std::uint32_t* p, int a, std::uint32_t last) { bits.set_run(p, a, last); },
      [&](std::uint32_t, const std::uint32_t* p, std::uint64_t mask) { bits.set_leaf(p, mask); },
      [&](std::uint32_t, std::uint32_t x, std::uint32_t y, std::uint32_t z) {
        bits.set(BrickBits::index(x, y, z));
      });
}

VoxelLeaves voxelize_brick_leaves(const GridMesh& mesh, std::span<const std::uint32_t> triangles,
                                  const Brick& brick, std::uint32_t side) {
  BitsLease lease(side);
  BrickBits& bits = lease.bits();
  rasterize_bits(mesh, triangles, brick, bits);
  VoxelLeaves out;
  const std::size_t leaves = bits.leaf_count();  // one allocation each, not a doubling series
  out.keys.reserve(leaves), out.masks.reserve(leaves);
  bits.for_each_leaf([&](std::size_t w, std::uint64_t mask) {
    out.keys.push_back(brick.first_key + w);
    out.masks.push_back(mask);
    out.voxel_count += std::uint64_t(std::popcount(mask));
  });
  return out;
}

struct BrickOutput {
  std::vector<std::uint64_t> codes;
  std::vector<std::uint32_t> normals;
};

// Codes from leaves, ascending.
void append_codes(const VoxelLeaves& leaves, std::vector<std::uint64_t>& codes) {
  codes.reserve(codes.size() + leaves.voxel_count);
  for (std::size_t k = 0; k < leaves.keys.size(); ++k)
    for (std::uint64_t m = leaves.masks[k]; m != 0; m &= m - 1)
      codes.push_back(leaves.keys[k] << 6 | std::uint64_t(std::countr_zero(m)));
}

// The brick's voxels with the octahedral sum of their triangles' unit normals, summed in
// ascending triangle order (as sorting (code, triangle) pairs would): a first pass sets the bits,
// whose ranks give each voxel its slot, and a second pass adds each triangle's normal there.
BrickOutput voxelize_brick_normals(const GridMesh& mesh, std::span<const std::uint32_t> triangles,
                                   const Brick& brick, std::uint32_t side) {
  BitsLease lease(side);
  BrickBits& bits = lease.bits();
  rasterize_bits(mesh, triangles, brick, bits);
  BrickOutput out;
  std::vector<std::uint32_t> rank(std::size_t(side) * side * side / 64);
  std::uint32_t total = 0;
  bits.for_each_leaf([&](std::size_t w, std::uint64_t mask) {
    rank[w] = total;
    total += std::uint32_t(std::popcount(mask));
    for (std::uint64_t m = mask; m != 0; m &= m - 1)
      out.codes.push_back((brick.first_key + w) << 6 | std::uint64_t(std::countr_zero(m)));
  });
  std::vector<double> sums(3 * std::size_t(total), 0.0);
  std::uint32_t current = ~0u;
  double unit[3] = {0, 0, 0};
  rasterize_voxels(mesh, triangles, brick, [&](std::uint32_t t, std::uint32_t i) {
    if (t != current) {
      const auto& tri = mesh.scene.triangles[t];
      const format::Double3 a = to_d(mesh.scene.positions[tri.v[0]]),
                            b = to_d(mesh.scene.positions[tri.v[1]]),
                            c = to_d(mesh.scene.positions[tri.v[2]]);
      const format::Double3 nrm = cross(b - a, c - a);
      const double length = std::sqrt(dot(nrm, nrm));
      for (int axis = 0; axis < 3; ++axis) unit[axis] = format::at(nrm, axis) / length;
      current = t;
    }
    const std::uint64_t below = bits.word(i >> 6) & ((std::uint64_t{1} << (i & 63)) - 1);
    double* sum = &sums[3 * (rank[i >> 6] + std::uint32_t(std::popcount(below)))];
    for (int axis = 0; axis < 3; ++axis) sum[axis] += unit[axis];
  });
  out.normals.resize(total);
  for (std::size_t k = 0; k < total; ++k)
    out.normals[k] = format::encode_octahedral(float(sums[3 * k]), float(sums[3 * k + 1]),
                                               float(sums[3 * k + 2]));
  return out;
}

// emit(b) for each brick (Morton index within `cube`, bricks of side `brick`) that triangle t's
// voxels may reach. When its candidate range spans at most two bricks, both (a triangle near a
// brick face nearly always reaches both, and setting it up here costs as much as a wasted setup
// in the walk); otherwise over each column of bricks along the triangle's dominant axis only the
// bricks its plane's slab (with margin) meets, not its whole bounding box.
template <class Emit>
void bricks_reached(const GridTriangle& t, const VoxelRange& whole, std::uint32_t brick,
                    TriangleColumns& columns, Emit emit) {
  const VoxelRange r = candidate_range(t, whole);
  if (is_empty(r)) return;
  const int shift = std::countr_zero(brick);  // r lies in `whole`: shifts, not 64-bit divisions
  std::int64_t lo[3], hi[3];
  for (int k = 0; k < 3; ++k)
    lo[k] = (r.lo[k] - whole.lo[k]) >> shift, hi[k] = (r.hi[k] - whole.lo[k]) >> shift;
  if ((hi[0] - lo[0] + 1) * (hi[1] - lo[1] + 1) * (hi[2] - lo[2] + 1) <= 2) {
    std::int64_t b[3];
    for (b[2] = lo[2]; b[2] <= hi[2]; ++b[2])
      for (b[1] = lo[1]; b[1] <= hi[1]; ++b[1])
        for (b[0] = lo[0]; b[0] <= hi[0]; ++b[0])
          emit(format::morton_code(std::uint32_t(b[0]), std::uint32_t(b[1]), std::uint32_t(b[2])));
    return;
  }
  if (!columns.setup(t)) return;
  const int a = columns.dominant_axis(), u = (a + 1) % 3, v = (a + 2) % 3;
  std::int64_t b[3];
  for (b[u] = lo[u]; b[u] <= hi[u]; ++b[u])
    for (b[v] = lo[v]; b[v] <= hi[v]; ++b[v]) {
      const std::int64_t u0 = std::max(r.lo[u], whole.lo[u] + b[u] * brick),
                         u1 = std::min(r.hi[u], whole.lo[u] + b[u] * brick + brick - 1),
                         v0 = std::max(r.lo[v], whole.lo[v] + b[v] * brick),
                         v1 = std::min(r.hi[v], whole.lo[v] + b[v] * brick + brick - 1);
      std::int64_t a0, a1;
      columns.reach_along_a(u0, u1, v0, v1, a0, a1);
      a0 = std::max(a0, r.lo[a]), a1 = std::min(a1, r.hi[a]);
      if (a0 > a1) continue;
      for (b[a] = (a0 - whole.lo[a]) >> shift; b[a] <= (a1 - whole.lo[a]) >> shift; ++b[a])
        emit(format::morton_code(std::uint32_t(b[0]), std::uint32_t(b[1]), std::uint32_t(b[2])));
    }
}

// Triangles in the bins of bricks: bin b holds items[offsets[b], offsets[b + 1]).
struct BrickBins {
  std::vector<std::size_t> offsets;
  std::vector<std::uint32_t> items;
  std::size_t size() const { return offsets.size() - 1; }
  std::span<std::uint32_t> bin(std::size_t b) {
    return {items.data() + offsets[b], offsets[b + 1] - offsets[b]};
  }
};

// Binning splits the triangles into this many consecutive ranges, a function of the counts alone
// (never of the thread count): ranges of at least 16k triangles, and at most 4M range-brick
// counters.
std::size_t bin_range_count(std::size_t triangles, std::size_t bricks) {
  const std::size_t by_size = (triangles + (std::size_t{1} << 14) - 1) >> 14;
  const std::size_t by_counters = std::max<std::size_t>(1, (std::size_t{1} << 22) / bricks);
  return std::max<std::size_t>(1, std::min(by_size, by_counters));
}

// Each of `triangles`, in the given order, in the bin of each brick of side `brick` it may reach
// (bricks_reached). In parallel and deterministic: each fixed range of triangles lists its
// (brick, triangle) pairs and counts them per brick; a brick's bin is then its ranges' entries
// in range order, so the order within a bin is the given order, whatever the thread count.
BrickBins bin_triangles(const GridMesh& mesh, const VoxelCube& cube,
                        std::span<const std::uint32_t> triangles, std::uint32_t brick,
                        unsigned threads) {
  const std::size_t per_axis = cube.side / brick, bricks = per_axis * per_axis * per_axis;
  const std::size_t ranges = bin_range_count(triangles.size(), bricks);
  const VoxelRange whole = range_of(cube);
  std::vector<std::uint32_t> counts(ranges * bricks, 0);  // then each range's start in a bin
  std::vector<std::vector<std::uint64_t>> pairs(ranges);  // brick << 32 | triangle
  parallel_for(ranges, threads, [&](std::size_t k) {
    const std::size_t first = triangles.size() * k / ranges,
                      last = triangles.size() * (k + 1) / ranges;
    std::uint32_t* count = counts.data() + k * bricks;
    pairs[k].reserve(last - first + (last - first) / 8);  // most triangles reach one brick
    TriangleColumns columns;
    for (std::size_t j = first; j < last; ++j) {
      if (j + 8 < last) mesh.prefetch_corners(triangles[j + 8]);
      const std::uint32_t i = triangles[j];
      bricks_reached(mesh.triangle(i), whole, brick, columns, [&](std::uint64_t b) {
        ++count[b];
        pairs[k].push_back(b << 32 | i);
      });
    }
  });
  BrickBins out;
  out.offsets.assign(bricks + 1, 0);
  for (std::size_t k = 0; k < ranges; ++k)  // row by row: the counts of a range are contiguous
    for (std::size_t b = 0; b < bricks; ++b) out.offsets[b + 1] += counts[k * bricks + b];
  for (std::size_t b = 0; b < bricks; ++b) out.offsets[b + 1] += out.offsets[b];
  std::vector<std::uint32_t> filled(bricks, 0);
  for (std::size_t k = 0; k < ranges; ++k)
    for (std::size_t b = 0; b < bricks; ++b) {
      std::uint32_t& c = counts[k * bricks + b];
      const std::uint32_t here = c;
      c = filled[b], filled[b] += here;
    }
  out.items.resize(out.offsets[bricks]);
  parallel_for(ranges, threads, [&](std::size_t k) {
    std::uint32_t* start = counts.data() + k * bricks;
    for (const std::uint64_t p : pairs[k])
      out.items[out.offsets[p >> 32] + start[p >> 32]++] = std::uint32_t(p);
    std::vector<std::uint64_t>().swap(pairs[k]);
  });
  return out;
}

// Faults in the pages of v's capacity on all threads (MADV_POPULATE_WRITE, Linux 5.14 on;
// elsewhere, or when refused, nothing), so that filling it later takes no page fault on one
// thread. The contents are left as they are.
template <class T>
void populate(std::vector<T>& v, unsigned threads) {
#if defined(__linux__) && defined(MADV_POPULATE_WRITE)
  constexpr std::uintptr_t kPage = 4096, kChunk = std::uintptr_t{1} << 21;
  const auto begin = (reinterpret_cast<std::uintptr_t>(v.data()) + kPage - 1) & ~(kPage - 1);
  const auto end = reinterpret_cast<std::uintptr_t>(v.data() + v.capacity()) & ~(kPage - 1);
  if (end <= begin + kChunk) return;  // small: not worth the threads
  parallel_for((end - begin + kChunk - 1) / kChunk, threads, [&](std::size_t c) {
    const std::uintptr_t from = begin + c * kChunk, to = std::min(end, from + kChunk);
    ::madvise(reinterpret_cast<void*>(from), to - from, MADV_POPULATE_WRITE);
  });
#else
  (void)v, (void)threads;
#endif
}

}  // namespace

double voxelizer_binning_bytes(std::uint32_t side, std::size_t triangles) {
  const std::size_t per_axis = std::max<std::uint32_t>(1, side / kBrickSide);
  const std::size_t bricks = per_axis * per_axis * per_axis;
  // Offsets (8 bytes a brick), counters (4 a brick and range), and per binned triangle a
  // (brick, triangle) pair and its place in the bins (8 + 4 bytes).
  return double(bricks) * double(8 + 4 * bin_range_count(triangles, bricks)) +
         12.0 * double(triangles);
}

VoxelGrid fit_voxel_grid(const format::Box3f& bounds, std::uint32_t resolution) {
  const double lo[3] = {bounds.min.x, bounds.min.y, bounds.min.z};
  const double hi[3] = {bounds.max.x, bounds.max.y, bounds.max.z};
  double side = 0;
  for (int a = 0; a < 3; ++a) side = std::max(side, hi[a] - lo[a]);
  if (!(side > 0)) side = 1;  // a single point: any cube around it
  VoxelGrid grid;
  grid.resolution = resolution;
  // Centred, but never past the bounds: rounding must not leave a face of the scene outside the
  // grid (a triangle lying in it would then touch no voxel). The voxel grows by a few ulps when
  // needed so the max corner, as to_grid computes it, is at most `resolution`.
  double size = side / resolution;
  for (int a = 0; a < 3; ++a) {
    grid.origin[a] = std::min(lo[a], 0.5 * (lo[a] + hi[a]) - 0.5 * side);
    size = std::max(size, (hi[a] - grid.origin[a]) / resolution);
  }
  for (int a = 0, tries = 0; a < 3 && tries < 64;)
    if ((hi[a] - grid.origin[a]) / size > resolution || grid.origin[a] + size * resolution < hi[a])
      size = std::nextafter(size, INFINITY), ++tries;
    else
      ++a;
  grid.voxel_size = size;
  return grid;
}

GridTriangle to_grid(const VoxelGrid& grid, const format::Float3& a, const format::Float3& b,
                     const format::Float3& c) {
  GridTriangle t;
  t.v[0] = grid_point(grid, a), t.v[1] = grid_point(grid, b), t.v[2] = grid_point(grid, c);
  return t;
}

bool triangle_touches_voxel(const GridTriangle& t, std::uint32_t x, std::uint32_t y,
                            std::uint32_t z) {
  const format::Double3 lo{double(x), double(y), double(z)};
  const format::Double3 hi{double(x) + 1, double(y) + 1, double(z) + 1};
  return triangle_overlaps_box(t.v[0], t.v[1], t.v[2], lo, hi);
}

bool is_valid_cube(const VoxelGrid& grid, const VoxelCube& cube) {
  if (cube.side < 4 || (cube.side & (cube.side - 1)) != 0 || cube.side > grid.resolution)
    return false;
  for (const std::uint32_t o : cube.origin)
    if (o % cube.side != 0 || std::uint64_t(o) + cube.side > grid.resolution) return false;
  return true;
}

std::vector<std::uint32_t> triangles_reaching(const Scene& scene, const VoxelGrid& grid,
                                              const VoxelCube& cube) {
  const VoxelRange clip = range_of(cube);
  std::vector<std::uint32_t> out;
  for (std::uint32_t i = 0; i < scene.triangles.size(); ++i)
    if (!is_empty(candidate_range(grid_triangle(scene, grid, i), clip))) out.push_back(i);
  return out;
}

Voxels voxelize_surface_cube(const Scene& scene, const VoxelGrid& grid, const VoxelCube& cube,
                             std::span<const std::uint32_t> triangles, bool normals,
                             unsigned threads) {
  if (!is_valid_cube(grid, cube)) throw std::invalid_argument("voxel cube outside the grid");
  Voxels out;
  out.grid = grid;
  const std::uint32_t brick = std::min(cube.side, kBrickSide);
  const GridMesh mesh(scene, grid, triangles.size(), threads);
  BrickBins bins = bin_triangles(mesh, cube, triangles, brick, threads);
  std::vector<BrickOutput> bricks(bins.size());
  parallel_for(bins.size(), threads, [&](std::size_t b) {
    const std::span<std::uint32_t> bin = bins.bin(b);
    if (bin.empty()) return;
    const Brick frame = brick_of(cube, brick, b);
    if (normals) {
      // Normals are summed in ascending triangle order, whatever order the caller gave.
      if (!std::is_sorted(bin.begin(), bin.end())) std::sort(bin.begin(), bin.end());
      bricks[b] = voxelize_brick_normals(mesh, bin, frame, brick);
    } else {
      append_codes(voxelize_brick_leaves(mesh, bin, frame, brick), bricks[b].codes);
    }
  });
  bins = {};
  std::size_t total = 0;
  for (const auto& b : bricks) total += b.codes.size();
  out.codes.reserve(total);
  if (normals) out.normals.reserve(total);
  populate(out.codes, threads), populate(out.normals, threads);
  for (auto& b : bricks) {  // bricks in Morton order give the global order
    out.codes.insert(out.codes.end(), b.codes.begin(), b.codes.end());
    out.normals.insert(out.normals.end(), b.normals.begin(), b.normals.end());
    b = {};
  }
  return out;
}

VoxelLeaves voxelize_surface_leaves(const Scene& scene, const VoxelGrid& grid,
                                    const VoxelCube& cube, std::span<const std::uint32_t> triangles,
                                    unsigned threads) {
  if (!is_valid_cube(grid, cube)) throw std::invalid_argument("voxel cube outside the grid");
  const std::uint32_t brick = std::min(cube.side, kBrickSide);
  const GridMesh mesh(scene, grid, triangles.size(), threads);
  BrickBins bins = bin_triangles(mesh, cube, triangles, brick, threads);
  std::vector<VoxelLeaves> bricks(bins.size());
  parallel_for(bins.size(), threads, [&](std::size_t b) {
    const std::span<const std::uint32_t> bin = bins.bin(b);
    if (bin.empty()) return;
    bricks[b] = voxelize_brick_leaves(mesh, bin, brick_of(cube, brick, b), brick);
  });
  bins = {};
  VoxelLeaves out;
  std::size_t total = 0;
  for (const auto& b : bricks) total += b.keys.size();
  out.keys.reserve(total);
  out.masks.reserve(total);
  populate(out.keys, threads), populate(out.masks, threads);
  for (auto& b : bricks) {
    out.keys.insert(out.keys.end(), b.keys.begin(), b.keys.end());
    out.masks.insert(out.masks.end(), b.masks.begin(), b.masks.end());
    out.voxel_count += b.voxel_count;
    b = {};
  }
  return out;
}

Voxels voxelize_surface(const Scene& scene, const VoxelizeOptions& options) {
  const std::uint32_t n = options.resolution;
  if (!format::is_valid_voxel_resolution(n))
    throw std::invalid_argument("--resolution " + std::to_string(n) +
                                " must be a power of two in " +
                                std::to_string(format::kVoxelMinResolution) + ".." +
                                std::to_string(format::kVoxelMaxResolution));
  const VoxelGrid grid = fit_voxel_grid(scene.bounds, n);
  std::vector<std::uint32_t> all(scene.triangles.size());
  for (std::uint32_t i = 0; i < all.size(); ++i) all[i] = i;
  return voxelize_surface_cube(scene, grid, VoxelCube{{0, 0, 0}, n}, all, options.normals,
                               options.threads);
}

}  // namespace kiln
