// The quadtree view: its validating walk and its leaf cells (quadtree_open.cpp opens it from a
// blob).
#include <string>
#include <vector>

#include "kiln/runtime/error.hpp"
#include "kiln/runtime/quadtree.hpp"

namespace kiln {

namespace {

struct Pending {
  std::uint32_t node, depth;
};

// Checks the children of interior node `index` (at `depth`): they tile its node range
// (index + 1 .. end) and its point range in ascending quadrant order; pushes them.
template <class Fail>
void check_children(std::span<const format::QuadNode> nodes, std::uint32_t index,
                    std::uint32_t depth, std::vector<Pending>& stack, Fail fail) {
  const format::QuadNode& n = nodes[index];
  const auto where = [&] { return "node " + std::to_string(index); };
  if (n.end() <= index + 1) fail(where() + " is interior but has no children");
  std::uint64_t next_point = n.first;
  std::uint32_t child = index + 1;
  int last_quadrant = -1;
  while (child != n.end()) {
    const format::QuadNode& c = nodes[child];  // child < n.end() <= nodes.size()
    if (c.end() <= child || c.end() > n.end())
      fail("node " + std::to_string(child) + " ends outside its parent");
    if (int(c.quadrant()) <= last_quadrant)
      fail("node " + std::to_string(child) + " repeats or reorders a quadrant");
    if (c.first != next_point || c.count == 0)
      fail("node " + std::to_string(child) + " has points out of order or none");
    last_quadrant = int(c.quadrant());
    next_point += c.count;
    stack.push_back({child, depth + 1});
    child = c.end();
  }
  if (next_point != std::uint64_t(n.first) + n.count)
    fail(where() + "'s children do not hold exactly its points");
}

}  // namespace

QuadtreeView::QuadtreeView(std::span<const format::QuadNode> nodes,
                           std::span<const format::Double2> points,
                           std::span<const std::uint32_t> ids, const format::Box2d& root,
                           std::uint64_t table_points, const std::string& name)
    : nodes_(nodes), points_(points), ids_(ids), root_(root), table_points_(table_points) {
  auto fail = [&](const std::string& what) { throw BlobError(name + ": " + what); };
  if (points.size() != ids.size())
    fail(std::to_string(points.size()) + " points but " + std::to_string(ids.size()) + " ids");
  if (nodes.empty()) fail("no nodes");
  if (nodes.size() > format::kQuadMaxNodes) fail("more nodes than the format allows");
  const format::QuadNode& top = nodes[0];
  if (top.first != 0 || top.count != points.size() || top.end() != nodes.size())
    fail("the root does not span every node and point");
  std::vector<Pending> stack{{0, 0}};
  while (!stack.empty()) {
    const Pending p = stack.back();
    stack.pop_back();
    if (p.depth > format::kQuadMaxDepth)
      fail("deeper than " + std::to_string(format::kQuadMaxDepth));
    const format::QuadNode& n = nodes[p.node];
    if (n.is_leaf()) {
      if (n.end() != p.node + 1) fail("leaf " + std::to_string(p.node) + " claims children");
      continue;
    }
    check_children(nodes, p.node, p.depth, stack, fail);
  }
  for (std::size_t i = 0; i < ids.size(); ++i)
    if (ids[i] >= table_points)
      fail("point " + std::to_string(i) + " names table point " + std::to_string(ids[i]) + " of " +
           std::to_string(table_points));
}

void QuadtreeView::cells(std::vector<IndexCell2>& out) const {
  out.clear();
  struct Cell {
    std::uint32_t node, level;
    format::Box2d box;
  };
  std::vector<Cell> stack{{0, 0, root_}};
  std::vector<Cell> children;
  while (!stack.empty()) {
    const Cell c = stack.back();
    stack.pop_back();
    const format::QuadNode& n = nodes_[c.node];
    if (n.is_leaf()) {
      out.push_back({c.box, c.level, n.count});
      continue;
    }
    children.clear();
    for (std::uint32_t k = c.node + 1; k < n.end(); k = nodes_[k].end())
      children.push_back({k, c.level + 1, format::quad_child_cell(c.box, nodes_[k].quadrant())});
    stack.insert(stack.end(), children.rbegin(), children.rend());  // the first child on top
  }
}

}  // namespace kiln
