// Subtrees built apart (on their own threads) and joined into the depth-first node array, shared
// by the binned and sweep builders.
#pragma once

#include <vector>

#include "kiln/formats/bvh.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln {

// Appends `sub` (a subtree emitted on its own, indices from 0) to `nodes`, shifting its interior
// nodes' second-child indices; leaf offsets index the shared reference order and stay.
inline void append_bvh_subtree(std::vector<format::BvhNode>& nodes,
                               const std::vector<format::BvhNode>& sub) {
  const auto shift = std::uint32_t(nodes.size());
  for (format::BvhNode n : sub) {
    if (n.count == 0) n.offset += shift;
    nodes.push_back(n);
  }
}

// Emits a node's two children after it with `emit(child, nodes)`: in turn, or (with `fork`)
// apart, the right one on its own thread, then appended in order, so the nodes are the same
// either way. Links the node at `index` to its second child and makes it interior.
template <class Child, class Emit>
void emit_bvh_children(bool fork, const Child& left, const Child& right, std::size_t index,
                       std::vector<format::BvhNode>& nodes, const Emit& emit) {
  std::uint32_t second;
  if (fork) {
    std::vector<format::BvhNode> l, r;
    fork_join(
        true, [&] { emit(left, l); }, [&] { emit(right, r); });
    nodes.reserve(nodes.size() + l.size() + r.size());
    append_bvh_subtree(nodes, l);
    second = std::uint32_t(nodes.size());
    append_bvh_subtree(nodes, r);
  } else {
    emit(left, nodes);
    second = std::uint32_t(nodes.size());
    emit(right, nodes);
  }
  nodes[index].offset = second;
  nodes[index].count = 0;
}

}  // namespace kiln
