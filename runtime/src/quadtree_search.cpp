// Quadtree queries. Range: depth first over the cells that meet the box, a cell inside the box
// reported whole (its subtree's points are one contiguous run), so the work is O(sqrt(n) + k)
// on spread-out points. Nearest: best first over cells ordered by their distance to the query
// (Hjaltason and Samet 1999), the k best so far in a bounded max-heap. Radius: depth first over
// cells within the radius.
//
// Exactness: a cell's distance takes, per axis, the rounded difference between the query and the
// cell's nearer side; every point of the cell lies beyond that side, and rounding is monotone, so
// the bound never exceeds the distance format::distance_squared gives any point of the cell, and
// pruning on `bound > worst` loses no point that could win, ties included.
#include <algorithm>
#include <array>
#include <cmath>

#include "kiln/runtime/quadtree.hpp"

namespace kiln {

namespace {

// A stack deep enough for any validated tree: at most three pending siblings per level, and
// the node being expanded.
constexpr std::size_t kStackSize = 4 * (format::kQuadMaxDepth + 2);

struct Pending {
  std::uint32_t node;
  format::Box2d cell;
};

bool inside(const format::Box2d& cell, const format::Box2d& box) {
  return box.min.x <= cell.min.x && cell.max.x <= box.max.x && box.min.y <= cell.min.y &&
         cell.max.y <= box.max.y;
}

double cell_distance_squared(const format::Box2d& c, const format::Double2& q) {
  const double dx = q.x < c.min.x ? c.min.x - q.x : q.x > c.max.x ? q.x - c.max.x : 0.0;
  const double dy = q.y < c.min.y ? c.min.y - q.y : q.y > c.max.y ? q.y - c.max.y : 0.0;
  return dx * dx + dy * dy;
}

bool closer2(const Neighbor2& a, const Neighbor2& b) {
  return a.distance_squared < b.distance_squared ||
         (a.distance_squared == b.distance_squared && a.index < b.index);
}

// Pushes the children of interior `p` whose cells `keep` accepts, the first child on top.
template <class Keep>
void push_children(std::span<const format::QuadNode> nodes, const Pending& p,
                   std::array<Pending, kStackSize>& stack, std::size_t& top, Keep keep) {
  const format::QuadNode& n = nodes[p.node];
  std::array<Pending, 4> children;
  std::size_t count = 0;
  for (std::uint32_t c = p.node + 1; c < n.end(); c = nodes[c].end()) {
    const format::Box2d cell = format::quad_child_cell(p.cell, nodes[c].quadrant());
    if (keep(cell)) children[count++] = {c, cell};
  }
  while (count > 0) stack[top++] = children[--count];
}

// Sorts the k indices (all below n) of an answer ascending. Long answers of large boxes would
// cost more to sort by comparison than to find: a dense one (k >= n / 32) is marked in a bitmap
// of n bits and read back in order, O(n / 64 + k); a sparse one is radix sorted, least
// significant digit first, 11 bits at a time, one stable counting pass per digit n needs.
void sort_indices(std::vector<std::uint32_t>& ids, std::size_t n) {
  if (ids.size() < 512) {
    std::sort(ids.begin(), ids.end());
    return;
  }
  if (ids.size() >= n / 32) {
    std::vector<std::uint64_t> bits((n + 63) / 64);
    for (const auto id : ids) bits[id >> 6] |= std::uint64_t{1} << (id & 63);
    std::size_t k = 0;
    for (std::size_t w = 0; w < bits.size(); ++w)
      for (std::uint64_t word = bits[w]; word != 0; word &= word - 1)
        ids[k++] = std::uint32_t(w * 64 + std::size_t(__builtin_ctzll(word)));
    ids.resize(k);  // fewer only when forged ids repeat: nothing is read or written past k
    return;
  }
  std::vector<std::uint32_t> scratch(ids.size());
  for (int shift = 0; shift < 32 && (std::uint64_t(n - 1) >> shift) != 0; shift += 11) {
    std::array<std::uint32_t, 2049> start{};
    for (const auto id : ids) start[((id >> shift) & 2047u) + 1] += 1;
    for (std::size_t d = 1; d < start.size(); ++d) start[d] += start[d - 1];
    for (const auto id : ids) scratch[start[(id >> shift) & 2047u]++] = id;
    ids.swap(scratch);
  }
}

}  // namespace

template <bool kCount>
void QuadtreeView::range_impl(const format::Box2d& box, std::vector<std::uint32_t>& out,
                              Cost* cost) const {
  out.clear();
  if (!(box.min.x <= box.max.x && box.min.y <= box.max.y) || !root_.overlaps(box)) return;
  std::array<Pending, kStackSize> stack;
  std::size_t top = 0;
  stack[top++] = {0, root_};
  while (top > 0) {
    const Pending p = stack[--top];
    const format::QuadNode& n = nodes_[p.node];
    if constexpr (kCount) cost->nodes += 1;
    if (inside(p.cell, box)) {
      out.insert(out.end(), ids_.begin() + n.first, ids_.begin() + n.first + n.count);
    } else if (n.is_leaf()) {
      for (std::uint32_t i = n.first; i < n.first + n.count; ++i)
        if (box.contains(points_[i])) out.push_back(ids_[i]);
      if constexpr (kCount) cost->tests += n.count;
    } else {
      push_children(nodes_, p, stack, top, [&](const format::Box2d& c) { return c.overlaps(box); });
    }
  }
  sort_indices(out, table_points_);
}

void QuadtreeView::range(const format::Box2d& box, std::vector<std::uint32_t>& out) const {
  range_impl<false>(box, out, nullptr);
}

void QuadtreeView::range_counting(const format::Box2d& box, std::vector<std::uint32_t>& out,
                                  Cost& cost) const {
  range_impl<true>(box, out, &cost);
}

std::size_t QuadtreeView::nearest(const format::Double2& q, std::span<Neighbor2> out) const {
  const std::size_t k = out.size();
  if (k == 0 || std::isnan(q.x) || std::isnan(q.y)) return 0;  // no order among NaN distances
  struct Cell {
    double bound;
    std::uint32_t node;
    format::Box2d box;
    bool operator<(const Cell& o) const {  // a max-heap on this is a min-heap on bound
      return bound > o.bound || (bound == o.bound && node > o.node);
    }
  };
  std::vector<Cell> queue;
  queue.reserve(64);
  queue.push_back({cell_distance_squared(root_, q), 0, root_});
  std::size_t size = 0;  // out[0, size) is a max-heap by closer2: the worst on top
  while (!queue.empty()) {
    std::pop_heap(queue.begin(), queue.end());
    const Cell c = queue.back();
    queue.pop_back();
    if (size == k && c.bound > out[0].distance_squared) break;
    const format::QuadNode& n = nodes_[c.node];
    if (!n.is_leaf()) {
      for (std::uint32_t child = c.node + 1; child < n.end(); child = nodes_[child].end()) {
        const format::Box2d box = format::quad_child_cell(c.box, nodes_[child].quadrant());
        const double bound = cell_distance_squared(box, q);
        if (size == k && bound > out[0].distance_squared) continue;
        queue.push_back({bound, child, box});
        std::push_heap(queue.begin(), queue.end());
      }
      continue;
    }
    for (std::uint32_t i = n.first; i < n.first + n.count; ++i) {
      const Neighbor2 candidate{format::distance_squared(points_[i], q), ids_[i]};
      if (size < k) {
        out[size++] = candidate;
        std::push_heap(out.begin(), out.begin() + std::ptrdiff_t(size), closer2);
      } else if (closer2(candidate, out[0])) {
        std::pop_heap(out.begin(), out.end(), closer2);
        out[k - 1] = candidate;
        std::push_heap(out.begin(), out.end(), closer2);
      }
    }
  }
  std::sort_heap(out.begin(), out.begin() + std::ptrdiff_t(size), closer2);
  return size;
}

void QuadtreeView::within_radius(const format::Double2& q, double radius,
                                 std::vector<Neighbor2>& out) const {
  out.clear();
  const double r2 = radius * radius;
  if (std::isnan(q.x) || std::isnan(q.y) || !(cell_distance_squared(root_, q) <= r2)) return;
  std::array<Pending, kStackSize> stack;
  std::size_t top = 0;
  stack[top++] = {0, root_};
  while (top > 0) {
    const Pending p = stack[--top];
    const format::QuadNode& n = nodes_[p.node];
    if (!n.is_leaf()) {
      push_children(nodes_, p, stack, top,
                    [&](const format::Box2d& c) { return cell_distance_squared(c, q) <= r2; });
      continue;
    }
    for (std::uint32_t i = n.first; i < n.first + n.count; ++i) {
      const double d2 = format::distance_squared(points_[i], q);
      if (d2 <= r2) out.push_back({d2, ids_[i]});
    }
  }
  std::sort(out.begin(), out.end(), closer2);
}

}  // namespace kiln
