// The voxel DAG built cube by cube (Kampe, Sintorn, Assarsson 2013, section 4), so that memory
// follows the DAG and one cube, not the grid's surface voxels. The cubes form an octree walked
// depth first in Morton order: a cube too large for the budget is split into its eight octants,
// each taking the triangles of its parent that reach it; a cube small enough is voxelized to
// 4x4x4 leaves and reduced to its node through the shared per-level tables; a split cube's node
// is made from its octants' nodes on the way back up. Every level's nodes are therefore met in
// Morton order, which is what makes the ids, and so the words, independent of the cut.
//
// With more than one thread the cubes are voxelized one ahead on a thread of their own: the
// reduction is sequential (ids follow the order of arrival), so it overlaps the next cube's
// voxelization instead of leaving the other cores idle. Both threads walk the same octree (the
// cut is a pure function of the cube and its triangles), so they meet the same cubes in order.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>

#include "kiln/compiler/voxel_dag_builder.hpp"
#include "kiln/runtime/parallel.hpp"
#include "voxel_dag_reducer.hpp"

namespace kiln {

namespace {

// Working bytes per surface voxel of a cube: voxelize_surface_cube's codes (8, twice while its
// bricks are concatenated), then the leaves (16 per 4x4x4 block) and their reduction (12 per
// block); a block holds at least one voxel.
constexpr double kBytesPerVoxel = 32;
// Budget-driven splitting stops here: below, the per-cube overhead dominates.
constexpr std::uint32_t kMinCubeSide = 64;

// A triangle's candidate voxels (as the voxelizer computes them, unclipped) and a bound on the
// voxels it sets.
struct TriangleReach {
  std::int32_t lo[3], hi[3];
  float voxels;
};

// Every voxel a triangle touches lies within sqrt(3) of it, and voxels are disjoint, so their
// count is at most the volume of that neighbourhood (Steiner's formula for a flat convex body:
// 2rA + (pi/2) r^2 P + (4/3) pi r^3).
double steiner_bound(double area, double perimeter) {
  const double r = std::sqrt(3.0);
  return 2 * r * area + M_PI / 2 * r * r * perimeter + 4.0 / 3.0 * M_PI * r * r * r;
}

double norm(const format::Double3& v) {
  return std::sqrt(dot(v, v));
}

TriangleReach reach_of(const GridTriangle& t) {
  TriangleReach reach;
  for (int a = 0; a < 3; ++a) {
    const double c[3] = {format::at(t.v[0], a), format::at(t.v[1], a), format::at(t.v[2], a)};
    // A box [k, k+1] touches a coordinate in [lo, hi] for k in [ceil(lo) - 1, floor(hi)].
    reach.lo[a] = std::int32_t(std::ceil(std::min({c[0], c[1], c[2]}))) - 1;
    reach.hi[a] = std::int32_t(std::floor(std::max({c[0], c[1], c[2]})));
  }
  const double area = 0.5 * norm(cross(t.v[1] - t.v[0], t.v[2] - t.v[0]));
  const double perimeter = norm(t.v[1] - t.v[0]) + norm(t.v[2] - t.v[1]) + norm(t.v[0] - t.v[2]);
  reach.voxels = float(steiner_bound(area, perimeter));
  return reach;
}

bool reaches(const TriangleReach& r, const VoxelCube& cube) {
  for (int a = 0; a < 3; ++a)
    if (std::int64_t(r.hi[a]) < cube.origin[a] ||
        std::int64_t(r.lo[a]) > std::int64_t(cube.origin[a]) + cube.side - 1)
      return false;
  return true;
}

// One voxelized cube at a time, handed from the thread that voxelizes the walk's cubes to the
// one that reduces them. The producer waits until its cube is taken before voxelizing the next,
// so at most two cubes (the one being reduced, the one being voxelized) are held at once.
class CubeMailbox {
 public:
  // Producer: hands `leaves` over and waits until taken; false when the consumer gave up.
  bool put(VoxelLeaves leaves) {
    std::unique_lock lock(mutex_);
    slot_ = std::move(leaves);
    changed_.notify_all();
    changed_.wait(lock, [&] { return !slot_ || cancelled_; });
    return !cancelled_;
  }
  void fail(std::exception_ptr error) {
    std::lock_guard lock(mutex_);
    error_ = error;
    changed_.notify_all();
  }
  // Consumer: the next cube's leaves; rethrows what the producer threw.
  VoxelLeaves take() {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return slot_ || error_; });
    if (!slot_) std::rethrow_exception(error_);
    VoxelLeaves leaves = std::move(*slot_);
    slot_.reset();
    changed_.notify_all();
    return leaves;
  }
  void cancel() {
    std::lock_guard lock(mutex_);
    cancelled_ = true;
    changed_.notify_all();
  }

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  std::optional<VoxelLeaves> slot_;
  std::exception_ptr error_;
  bool cancelled_ = false;
};

// Thrown through the producer's walk when the consumer stopped (it failed).
struct WalkCancelled {};

class CubeWalk {
 public:
  CubeWalk(const Scene& scene, const VoxelGrid& grid, const OutOfCoreDagOptions& options)
      : scene_(scene), grid_(grid), options_(options), reducer_(grid.resolution) {
    reach_.reserve(scene.triangles.size());
    for (const auto& tri : scene.triangles)
      reach_.push_back(reach_of(to_grid(grid, scene.positions[tri.v[0]], scene.positions[tri.v[1]],
                                        scene.positions[tri.v[2]])));
    budget_ = options.memory_budget ? options.memory_budget : default_memory_budget();
  }

  FlatVoxelDag run(OutOfCoreDagStats* stats);

 private:
  // What a walk does at each cube that is not split: plan it (count and weigh), voxelize it and
  // hand it to the mailbox, or reduce it (voxelizing it here, or taking it from the mailbox).
  enum class Pass { kPlan, kProduce, kReduce };

  double estimate(const VoxelCube& cube, std::span<const std::uint32_t> triangles) const;
  bool split(const VoxelCube& cube, std::span<const std::uint32_t> triangles) const;
  std::uint32_t walk(Pass pass, const VoxelCube& cube, std::span<const std::uint32_t> triangles);
  std::uint32_t leaf_cube(Pass pass, const VoxelCube& cube,
                          std::span<const std::uint32_t> triangles);
  std::uint32_t reduce_all(std::span<const std::uint32_t> all);

  const Scene& scene_;
  const VoxelGrid& grid_;
  const OutOfCoreDagOptions& options_;
  VoxelDagReducer reducer_;
  std::vector<TriangleReach> reach_;
  std::uint64_t budget_ = 0;
  CubeMailbox* mailbox_ = nullptr;  // set while a producer thread voxelizes ahead
  std::vector<double> planned_;     // estimated voxels per cube, from the planning pass
  double planned_total_ = 0, done_weight_ = 0;
  OutOfCoreDagStats stats_;
};

// A bound on the cube's surface voxels: each triangle's Steiner bound, capped by what a plane
// can set inside the cube (grown by sqrt(3)): a plane section of a cube of side e has area at
// most sqrt(2) e^2 and perimeter at most (2 + 2 sqrt(2)) e; the sum capped by the cube's volume.
double CubeWalk::estimate(const VoxelCube& cube, std::span<const std::uint32_t> triangles) const {
  const double e = cube.side + 2 * std::sqrt(3.0);
  const double plane = steiner_bound(std::sqrt(2.0) * e * e, (2 + 2 * std::sqrt(2.0)) * e);
  const double volume = double(cube.side) * cube.side * cube.side;
  double sum = 0;
  for (const std::uint32_t i : triangles) {
    sum += std::min(double(reach_[i].voxels), plane);
    if (sum >= volume) return volume;
  }
  return sum;
}

bool CubeWalk::split(const VoxelCube& cube, std::span<const std::uint32_t> triangles) const {
  if (options_.cube_side != 0) return cube.side > options_.cube_side;
  if (cube.side <= kMinCubeSide) return false;
  const double bytes = estimate(cube, triangles) * kBytesPerVoxel +
                       voxelizer_binning_bytes(cube.side, triangles.size());
  return bytes > double(budget_) / 4;
}

std::uint32_t CubeWalk::leaf_cube(Pass pass, const VoxelCube& cube,
                                  std::span<const std::uint32_t> triangles) {
  if (pass == Pass::kProduce) {
    if (!mailbox_->put(voxelize_surface_leaves(scene_, grid_, cube, triangles, options_.threads)))
      throw WalkCancelled{};
    return VoxelDagReducer::kEmpty;
  }
  const double weight = options_.progress ? estimate(cube, triangles) : 0;
  if (pass == Pass::kPlan) {
    planned_.push_back(weight), planned_total_ += weight;
    return VoxelDagReducer::kEmpty;
  }
  const VoxelLeaves leaves =
      mailbox_ ? mailbox_->take()
               : voxelize_surface_leaves(scene_, grid_, cube, triangles, options_.threads);
  const std::uint32_t id = reducer_.add_cube(leaves, cube);
  stats_.cubes += 1;
  stats_.smallest_side = stats_.cubes == 1 ? cube.side : std::min(stats_.smallest_side, cube.side);
  stats_.largest_side = std::max(stats_.largest_side, cube.side);
  stats_.largest_cube_voxels = std::max(stats_.largest_cube_voxels, leaves.voxel_count);
  if (options_.progress) {
    done_weight_ += weight;
    options_.progress(stats_.cubes, planned_.size(),
                      planned_total_ > 0 ? std::min(1.0, done_weight_ / planned_total_) : 1.0);
  }
  return id;
}

// The cube's node id (kEmpty when nothing is set); octants in Morton order, each with the
// triangles of `triangles` that reach it, held only while it is walked.
std::uint32_t CubeWalk::walk(Pass pass, const VoxelCube& cube,
                             std::span<const std::uint32_t> triangles) {
  if (!split(cube, triangles)) return leaf_cube(pass, cube, triangles);
  const std::uint32_t half = cube.side / 2;
  std::uint32_t children[8];
  std::vector<std::uint32_t> inside;
  for (std::uint32_t octant = 0; octant < 8; ++octant) {
    const VoxelCube child{
        {cube.origin[0] + (octant & 1) * half, cube.origin[1] + (octant >> 1 & 1) * half,
         cube.origin[2] + (octant >> 2 & 1) * half},
        half};
    inside.clear();
    for (const std::uint32_t i : triangles)
      if (reaches(reach_[i], child)) inside.push_back(i);
    children[octant] = inside.empty() ? VoxelDagReducer::kEmpty : walk(pass, child, inside);
  }
  std::vector<std::uint32_t>().swap(inside);
  if (pass != Pass::kReduce) return VoxelDagReducer::kEmpty;
  return reducer_.add_node(reducer_.level_of_side(cube.side), children);
}

FlatVoxelDag CubeWalk::run(OutOfCoreDagStats* stats) {
  const std::uint32_t n = grid_.resolution;
  if (options_.cube_side != 0 && (options_.cube_side < 4 || options_.cube_side > n ||
                                  (options_.cube_side & (options_.cube_side - 1)) != 0))
    throw std::invalid_argument("cube side " + std::to_string(options_.cube_side) +
                                " must be a power of two in 4.." + std::to_string(n));
  std::vector<std::uint32_t> all;
  for (std::uint32_t i = 0; i < reach_.size(); ++i)
    if (reaches(reach_[i], VoxelCube{{0, 0, 0}, n})) all.push_back(i);
  if (options_.progress) walk(Pass::kPlan, VoxelCube{{0, 0, 0}, n}, all);
  const std::uint32_t root = all.empty() ? VoxelDagReducer::kEmpty : reduce_all(all);
  std::vector<std::uint32_t>().swap(all);
  if (stats) *stats = stats_;
  return reducer_.finish(root);
}

// The root's id: the walk reducing every cube, voxelized here with one thread, else one ahead
// on a producer thread (the voxelizer still using every thread for its bricks).
std::uint32_t CubeWalk::reduce_all(std::span<const std::uint32_t> all) {
  const VoxelCube root{{0, 0, 0}, grid_.resolution};
  if (resolve_thread_count(options_.threads) < 2) return walk(Pass::kReduce, root, all);
  CubeMailbox mailbox;
  mailbox_ = &mailbox;  // read by both walks; reset only once the producer has joined
  std::thread producer([&] {
    try {
      walk(Pass::kProduce, root, all);
    } catch (const WalkCancelled&) {
    } catch (...) {
      mailbox.fail(std::current_exception());
    }
  });
  try {
    const std::uint32_t id = walk(Pass::kReduce, root, all);
    producer.join();
    mailbox_ = nullptr;
    return id;
  } catch (...) {
    mailbox.cancel();
    producer.join();
    mailbox_ = nullptr;
    throw;
  }
}

}  // namespace

FlatVoxelDag build_voxel_dag_out_of_core(const Scene& scene, const VoxelGrid& grid,
                                         const OutOfCoreDagOptions& options,
                                         OutOfCoreDagStats* stats) {
  CubeWalk walk(scene, grid, options);
  return walk.run(stats);
}

}  // namespace kiln
