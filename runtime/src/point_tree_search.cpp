// kNN and radius searches: depth first, nearer child first, the farther child pruned by the
// squared distance from the query to its side of the split gap, accumulated per axis (Arya and
// Mount's incremental distance, as nanoflann does it).
//
// Exactness: each per-axis bound is the square of (gap edge - query), where the gap edge lies
// between the query and every point of that subtree, and float subtraction, squaring and addition
// are monotone; so the bound, summed in the same order as a point's distance, never exceeds the
// float distance of any point it stands for, and pruning on `bound > worst` loses no point that
// could win, ties included.
#include <algorithm>
#include <limits>

#include "kiln/runtime/point_tree.hpp"

namespace kiln {

namespace {

float squared_distance(const format::Float3& p, const float q[3]) {
  const float dx = p.x - q[0], dy = p.y - q[1], dz = p.z - q[2];
  return (dx * dx + dy * dy) + dz * dz;
}

float sum_of(const float d[3]) {
  return (d[0] + d[1]) + d[2];
}

// The k best so far, kept sorted by (distance, id) in the caller's slots.
class NearestSet {
 public:
  explicit NearestSet(std::span<Neighbor> slots) : slots_(slots) {}
  float bound() const { return bound_; }
  void offer(std::uint32_t id, float distance2) {
    const Neighbor candidate{id, distance2};
    std::size_t i = size_;
    if (size_ < slots_.size()) {
      size_ += 1;
    } else {
      if (!closer(candidate, slots_[size_ - 1])) return;  // an equal distance with a higher id
      i = size_ - 1;
    }
    for (; i > 0 && closer(candidate, slots_[i - 1]); --i) slots_[i] = slots_[i - 1];
    slots_[i] = candidate;
    if (size_ == slots_.size()) bound_ = slots_[size_ - 1].distance2;
  }
  std::size_t size() const { return size_; }

 private:
  std::span<Neighbor> slots_;
  std::size_t size_ = 0;
  float bound_ = std::numeric_limits<float>::infinity();
};

class RadiusSet {
 public:
  RadiusSet(float radius2, std::vector<Neighbor>& out) : radius2_(radius2), out_(out) {}
  float bound() const { return radius2_; }
  void offer(std::uint32_t id, float distance2) { out_.push_back({id, distance2}); }

 private:
  float radius2_;
  std::vector<Neighbor>& out_;
};

// A subtree still to visit, with the per-axis bounds that hold for all its points.
struct Pending {
  std::uint32_t node;
  float dists[3];
  float sum;
};

// Depth first with an explicit stack (no calls per node): the far child is pushed with its
// tighter bounds, the near one is entered at once; a popped subtree is skipped when the best
// distance shrank below its bound meanwhile. The stack holds at most one entry per level.
template <class Set>
void search(const PointTreeView& tree, const float q[3], const float root[3], Set& set) {
  const format::PointNode* nodes = tree.nodes().data();
  const format::Float3* points = tree.points().data();
  const std::uint32_t* ids = tree.ids().data();
  Pending stack[format::kPointMaxDepth];
  std::uint32_t top = 0;
  Pending current{0, {root[0], root[1], root[2]}, sum_of(root)};
  for (;;) {
    const format::PointNode* n = &nodes[current.node];
    while (!n->is_leaf()) {
      const std::uint32_t axis = n->axis();
      const float to_below = q[axis] - n->below_max(), to_above = q[axis] - n->above_min();
      std::uint32_t near = current.node + 1, far = n->above_child();
      float cut = to_above * to_above;
      if (to_below + to_above >= 0.0f) {  // nearer the above side of the gap
        std::swap(near, far);
        cut = to_below * to_below;
      }
      Pending& other = stack[top];
      other = current;
      other.node = far;
      other.dists[axis] = std::max(current.dists[axis], cut);  // both bound the far points
      other.sum = sum_of(other.dists);
      top += other.sum <= set.bound();
      current.node = near;
      n = &nodes[near];
    }
    for (std::uint32_t i = n->first_point(), end = i + n->point_count(); i < end; ++i) {
      const float d2 = squared_distance(points[i], q);
      if (d2 <= set.bound()) set.offer(ids[i], d2);
    }
    do {
      if (top == 0) return;
      current = stack[--top];
    } while (current.sum > set.bound());
  }
}

// Per-axis squared distances from the query to the bounds of every point: the root's bound.
void root_distances(const PointTreeView& tree, const float q[3], float dists[3]) {
  for (int a = 0; a < 3; ++a) {
    float d = 0.0f;
    const float lo = format::at(tree.bounds().min, a), hi = format::at(tree.bounds().max, a);
    if (q[a] < lo) d = lo - q[a];
    if (q[a] > hi) d = q[a] - hi;
    dists[a] = d * d;
  }
}

}  // namespace

std::size_t PointTreeView::nearest(const format::Float3& query, std::span<Neighbor> out) const {
  if (out.empty()) return 0;
  const float q[3] = {query.x, query.y, query.z};
  float dists[3];
  root_distances(*this, q, dists);
  NearestSet set(out);
  search(*this, q, dists, set);
  return set.size();
}

void PointTreeView::within_radius(const format::Float3& query, float radius,
                                  std::vector<Neighbor>& out) const {
  out.clear();
  const float q[3] = {query.x, query.y, query.z};
  float dists[3];
  root_distances(*this, q, dists);
  RadiusSet set(radius * radius, out);
  if (sum_of(dists) <= set.bound()) search(*this, q, dists, set);
  std::sort(out.begin(), out.end(), closer);
}

}  // namespace kiln
