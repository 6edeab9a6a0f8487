// Subtrees built apart (on their own threads) and joined into the depth-first node array.
#pragma once

#include <vector>

#include "kiln/formats/bvh.hpp"

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

}  // namespace kiln
