// The ESVO builder's temporary tree (pbrt-style: build, then flatten): nodes are child
// descriptors not yet laid out, in blocks built independently.
#pragma once

#include <cstdint>
#include <vector>

#include "kiln/compiler/esvo_builder.hpp"

namespace kiln::esvo {

inline constexpr std::uint32_t kNoGroup = 0xFFFFFFFFu;

struct TempNode {
  std::uint8_t valid = 0, non_leaf = 0, contour_mask = 0;
  std::uint32_t level = 0;
  // The descriptors of the non-leaf children: nodes [first_child, first_child + popcount) of
  // this block, or (in the top block, for a node whose children start a block) that block's
  // index, with child_block set.
  std::uint32_t first_child = kNoGroup;
  bool child_block = false;
  std::uint32_t first_contour = 0;  // into TempBlock::contours, popcount(contour_mask) words
  std::uint32_t first_normal = 0;   // into TempBlock::normals, popcount(valid) entries
};

// A run of groups: every node's non-leaf children sit together, each group followed (after all
// its siblings) by its members' subtrees, so `groups` lists them in that order.
struct TempBlock {
  std::vector<TempNode> nodes;
  std::vector<std::uint32_t> contours;
  std::vector<std::uint32_t> normals;
  std::vector<std::uint32_t> colors;        // parallel to normals, when the scene has colours
  std::vector<std::uint32_t> group_starts;  // node index of each group, in allocation order
  std::vector<EsvoLevelStats> levels;
  std::uint64_t far_pointers = 0;
};

// Lays the blocks out (block 0 first, holding the root at node 0) into `out`'s words, pages,
// blocks and normals, and fills its statistics.
void flatten_blocks(std::vector<TempBlock>& blocks, FlatEsvo& out);

}  // namespace kiln::esvo
