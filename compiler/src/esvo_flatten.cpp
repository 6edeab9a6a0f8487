// Lays the ESVO's temporary blocks out as words. Within a block, a group (the descriptors of one
// node's non-leaf children) is followed by its far pointers and voxel runs, then by its members'
// subtrees in order, so child pointers are short and mostly near. Sizes are computed bottom up
// (groups in reverse allocation order); a group's far pointers lengthen its own header, so each
// group settles its near/far choice by a small fixed point (far pointers only ever get added).
#include <algorithm>
#include <bit>
#include <stdexcept>

#include "esvo_tree.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln::esvo {

namespace {

struct GroupLayout {
  std::uint64_t header = 0;   // descriptors, far pointers, runs, padding: words
  std::uint64_t subtree = 0;  // header plus every member's subtree
  std::uint32_t far_count = 0;
  std::uint64_t position = 0;  // word index, once placed
};

struct BlockLayout {
  std::vector<GroupLayout> groups;
  std::vector<bool> far;  // per node
};

std::uint32_t run_words(const TempNode& n) {
  return 1 + std::uint32_t(std::popcount(n.contour_mask));
}

std::size_t group_count(const TempBlock& block, std::size_t g) {
  const std::size_t end =
      g + 1 < block.group_starts.size() ? block.group_starts[g + 1] : block.nodes.size();
  return end - block.group_starts[g];
}

std::size_t group_of(const TempBlock& block, std::uint32_t first_node) {
  return std::size_t(
      std::lower_bound(block.group_starts.begin(), block.group_starts.end(), first_node) -
      block.group_starts.begin());
}

std::uint64_t child_subtree(const TempBlock& block, const BlockLayout& layout, const TempNode& n) {
  if (n.first_child == kNoGroup || n.child_block) return 0;
  return layout.groups[group_of(block, n.first_child)].subtree;
}

BlockLayout measure(const TempBlock& block) {
  BlockLayout layout;
  layout.groups.resize(block.group_starts.size());
  layout.far.assign(block.nodes.size(), false);
  for (std::size_t g = block.group_starts.size(); g-- > 0;) {
    const std::size_t first = block.group_starts[g], count = group_count(block, g);
    std::uint64_t runs = 0, below = 0;
    for (std::size_t i = 0; i < count; ++i) {
      runs += run_words(block.nodes[first + i]);
      below += child_subtree(block, layout, block.nodes[first + i]);
    }
    GroupLayout& gl = layout.groups[g];
    std::uint32_t far_count = 0;
    for (;;) {
      gl.header = 2 * count + far_count + runs;
      gl.header += gl.header & 1;  // the next group's descriptors start at an even word
      std::uint32_t needed = 0;
      std::uint64_t offset = gl.header;  // of the current member's children, from the group
      for (std::size_t i = 0; i < count; ++i) {
        const TempNode& n = block.nodes[first + i];
        const std::uint64_t distance = offset - 2 * i;
        const bool far = n.child_block ||
                         (n.first_child != kNoGroup && distance / 2 > format::kEsvoNearPointerMax);
        layout.far[first + i] = far;
        needed += far;
        offset += child_subtree(block, layout, n);
      }
      if (needed == far_count) break;
      far_count = needed;
    }
    gl.far_count = far_count;
    gl.subtree = gl.header + below;
  }
  return layout;
}

void place(const TempBlock& block, BlockLayout& layout, std::uint64_t start) {
  layout.groups[0].position = start;
  for (std::size_t g = 0; g < block.group_starts.size(); ++g) {
    const std::size_t first = block.group_starts[g], count = group_count(block, g);
    std::uint64_t offset = layout.groups[g].position + layout.groups[g].header;
    for (std::size_t i = 0; i < count; ++i) {
      const TempNode& n = block.nodes[first + i];
      if (n.first_child == kNoGroup || n.child_block) continue;
      GroupLayout& child = layout.groups[group_of(block, n.first_child)];
      child.position = offset;
      offset += child.subtree;
    }
  }
}

void write_block(const TempBlock& block, const BlockLayout& layout,
                 std::span<const std::uint64_t> block_starts, std::span<std::uint32_t> words) {
  for (std::size_t g = 0; g < block.group_starts.size(); ++g) {
    const std::size_t first = block.group_starts[g], count = group_count(block, g);
    const GroupLayout& gl = layout.groups[g];
    std::uint64_t far_word = gl.position + 2 * count;
    std::uint64_t run = far_word + gl.far_count;
    for (std::size_t i = 0; i < count; ++i) {
      const TempNode& n = block.nodes[first + i];
      const std::uint64_t at = gl.position + 2 * i;
      format::EsvoDescriptor d{};
      d.valid = n.valid, d.non_leaf = n.non_leaf, d.contour_mask = n.contour_mask;
      if (n.first_child != kNoGroup) {
        const std::uint64_t target = n.child_block
                                         ? block_starts[n.first_child]
                                         : layout.groups[group_of(block, n.first_child)].position;
        const std::uint64_t distance = target - at;
        if (layout.far[first + i]) {
          if (distance > 0xFFFFFFFFu)
            throw std::length_error("ESVO: a far pointer spans more than 2^32 words");
          d.far = true;
          d.child_pointer = std::uint32_t(far_word - at);
          words[far_word++] = std::uint32_t(distance);
        } else {
          d.child_pointer = std::uint32_t(distance / 2);
        }
      }
      if (run - at > format::kEsvoContourPointerMax)
        throw std::length_error("ESVO: a voxel run lies more than 2^24 words from its descriptor");
      d.contour_pointer = std::uint32_t(run - at);
      words[run++] = n.first_normal;
      for (int k = 0; k < std::popcount(n.contour_mask); ++k)
        words[run++] = block.contours[n.first_contour + k];
      format::encode_descriptor(d, words[at], words[at + 1]);
    }
  }
}

}  // namespace

void flatten_blocks(std::vector<TempBlock>& blocks, FlatEsvo& out) {
  std::vector<BlockLayout> layouts(blocks.size());
  parallel_for(blocks.size(), 0, [&](std::size_t b) { layouts[b] = measure(blocks[b]); });
  std::vector<std::uint64_t> starts(blocks.size());
  std::uint64_t total = 0, attachments = 0;
  out.blocks.clear();
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    starts[b] = total;
    out.blocks.push_back({total, attachments});
    total += layouts[b].groups[0].subtree;
    attachments += blocks[b].normals.size();
  }
  out.words.assign(total, 0);
  parallel_for(blocks.size(), 0, [&](std::size_t b) {
    place(blocks[b], layouts[b], starts[b]);
    write_block(blocks[b], layouts[b], starts, out.words);
  });
  out.normals.clear();
  out.normals.reserve(attachments);
  out.level_stats.assign(out.levels, {});
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    TempBlock& block = blocks[b];
    out.normals.insert(out.normals.end(), block.normals.begin(), block.normals.end());
    out.colors.insert(out.colors.end(), block.colors.begin(), block.colors.end());
    for (std::size_t l = 0; l < block.levels.size(); ++l) {
      EsvoLevelStats& s = out.level_stats[l];
      s.descriptors += block.levels[l].descriptors, s.voxels += block.levels[l].voxels;
      s.leaves += block.levels[l].leaves, s.contours += block.levels[l].contours;
    }
    for (const GroupLayout& g : layouts[b].groups) out.far_pointer_count += g.far_count;
    block = {};
  }
  out.pages.resize((total + format::kEsvoPageWords - 1) / format::kEsvoPageWords);
  for (std::size_t p = 0, b = 0; p < out.pages.size(); ++p) {
    const std::uint64_t word = std::uint64_t(p) * format::kEsvoPageWords;
    while (b + 1 < out.blocks.size() && out.blocks[b + 1].first_word <= word) ++b;
    out.pages[p] = std::uint32_t(b);
  }
  for (std::size_t l = 0; l < out.level_stats.size(); ++l) {
    const EsvoLevelStats& s = out.level_stats[l];
    out.descriptor_count += s.descriptors, out.voxel_count += s.voxels;
    out.leaf_count += s.leaves, out.contour_count += s.contours;
    if (s.leaves > 0) out.max_depth = std::uint32_t(l + 1);
  }
  out.contour_bytes = 4 * out.contour_count;
  out.attachment_bytes = 4 * (out.normals.size() + out.colors.size());
  out.hierarchy_bytes = 4 * out.words.size() - out.contour_bytes + 4 * out.pages.size() +
                        sizeof(format::EsvoBlockInfo) * out.blocks.size();
}

}  // namespace kiln::esvo
