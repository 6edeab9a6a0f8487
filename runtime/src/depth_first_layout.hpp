// Trees of two-way nodes in depth-first order (the below child next, the above child beside):
// the one structural check every such mapped tree gets before it is traversed, and the walk that
// hands each node its cell, for the deep checks.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "kiln/formats/vector.hpp"

namespace kiln {

// Walks `nodes` in pre-order from the root: the n-th node reached must be node n (no sharing,
// cycles or unreachable nodes), no leaf deeper than `max_depth` (root = 1), the above child after
// the below one (which is the next node), and the leaves' item ranges consecutive from 0 and
// covering exactly `item_count` items. Node must offer is_leaf(), above_child() and, through
// `range`, a leaf's (first, count). Calls `fail(message)`, which must throw, on the first problem.
// O(nodes).
template <class Node, class Range, class Fail>
void check_depth_first_layout(std::span<const Node> nodes, std::uint32_t max_depth,
                              std::uint64_t item_count, const char* items, Range range, Fail fail) {
  if (nodes.empty()) fail("no nodes");
  struct Pending {
    std::uint32_t node, depth;
  };
  std::vector<Pending> stack{{0, 1}};
  std::uint64_t next_node = 0, next_item = 0;
  while (!stack.empty()) {
    const Pending p = stack.back();
    stack.pop_back();
    if (p.node != next_node)
      fail("node " + std::to_string(next_node) + " is not where depth-first order puts it");
    if (p.depth > max_depth) fail("deeper than " + std::to_string(max_depth));
    const Node& n = nodes[p.node];
    next_node += 1;
    if (n.is_leaf()) {
      const auto [first, count] = range(n);
      if (first != next_item || count > item_count - next_item)
        fail("leaf " + std::to_string(p.node) + " has " + items + " out of order or out of range");
      next_item += count;
      continue;
    }
    if (n.above_child() <= p.node + 1u || n.above_child() >= nodes.size())
      fail("node " + std::to_string(p.node) + " has child index " +
           std::to_string(n.above_child()) + " out of range");
    stack.push_back({n.above_child(), p.depth + 1});
    stack.push_back({p.node + 1, p.depth + 1});
  }
  if (next_node != nodes.size())
    fail(std::to_string(nodes.size() - next_node) + " nodes are unreachable");
  if (next_item != item_count)
    fail(std::to_string(item_count - next_item) + " " + items + " are in no leaf");
}

// Depth-first walk of a tree that passed check_depth_first_layout, handing each node the cell
// it owns (a format::Box3f): the root's box `root`, cut on the way down by `split(index, node,
// below, above)`, which receives two copies of the parent's cell to narrow; each leaf gets
// `leaf(node, cell)`.
template <class Node, class Split, class Leaf>
void walk_tree_cells(std::span<const Node> nodes, const format::Box3f& root, Split split,
                     Leaf leaf) {
  struct Pending {
    std::uint32_t node;
    format::Box3f cell;
  };
  std::vector<Pending> stack{{0, root}};
  while (!stack.empty()) {
    const Pending p = stack.back();
    stack.pop_back();
    const Node& n = nodes[p.node];
    if (n.is_leaf()) {
      leaf(n, p.cell);
      continue;
    }
    Pending below{p.node + 1, p.cell}, above{n.above_child(), p.cell};
    split(p.node, n, below.cell, above.cell);
    stack.push_back(above);
    stack.push_back(below);
  }
}

}  // namespace kiln
