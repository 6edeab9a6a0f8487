// The SSVDAG view: the validating parse at open, pointer decoding and occupancy.
#include <bit>
#include <string>
#include <vector>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/ssvdag.hpp"
#include "voxel_grid_frame.hpp"

namespace kiln {

namespace {

// Visits every node of each interior level: f(level, word, header, pointer words) with the
// node's size checked against its level's end first (`fail` otherwise).
template <class Fail, class F>
void for_each_node(std::span<const std::uint16_t> words, std::span<const std::uint64_t> first,
                   std::uint32_t interior_levels, Fail fail, F f) {
  for (std::uint32_t l = 0; l < interior_levels; ++l)
    for (std::uint64_t w = first[l], end = first[l + 1]; w < end;) {
      const std::uint32_t header = words[w], mask = header & 0xFF, wide = header >> 8;
      if (mask == 0 || (wide & ~mask) != 0)
        fail("word " + std::to_string(w) + " is not a node header (" + std::to_string(header) +
             ")");
      const std::uint64_t size = 1 + std::popcount(mask) + std::popcount(wide);
      if (size > end - w) fail("node at word " + std::to_string(w) + " overruns its level");
      if (l == 0 && end != size) fail("level 0 holds more than the root");
      f(l, w, header);
      w += size;
    }
}

}  // namespace

SsvdagView::SsvdagView(std::span<const std::uint16_t> words, std::span<const std::uint64_t> leaves,
                       const VoxelGridFrame& frame,
                       std::span<const std::uint64_t> level_first_words, std::uint32_t root_mirror,
                       const std::string& name)
    : words_(words), leaves_(leaves), frame_(frame), root_mirror_(root_mirror) {
  auto fail = [&](const std::string& what) { throw BlobError(name + ": " + what); };
  if (const std::string problem = grid_frame_problem(frame, format::kVoxelMaxResolution);
      !problem.empty())
    fail(problem);
  levels_ = std::uint32_t(std::bit_width(frame.resolution) - 1);
  const std::uint32_t leaf_level = levels_ - 2;
  if (level_first_words.size() != leaf_level || leaf_level + 1 > first_.size())
    fail(std::to_string(level_first_words.size()) + " interior levels, expected " +
         std::to_string(leaf_level));
  if (root_mirror > 7) fail("root mirror " + std::to_string(root_mirror) + " is not 0..7");
  if (leaves.empty()) fail("has no leaves");
  std::copy(level_first_words.begin(), level_first_words.end(), first_.begin());
  first_[leaf_level] = words.size();
  if (first_[0] != 0) fail("the root is not at word 0");
  for (std::uint32_t l = 0; l < leaf_level; ++l)
    if (first_[l] >= first_[l + 1])
      fail("level " + std::to_string(l) + " is empty or out of order");

  std::vector<bool> starts(words.size());
  const std::span<const std::uint64_t> first(first_.data(), leaf_level + 1);
  for_each_node(words, first, leaf_level, fail,
                [&](std::uint32_t, std::uint64_t w, std::uint32_t) { starts[w] = true; });
  // Every pointer names a node start of the next level, or a leaf from the last interior level;
  // a relative one needs a wide pointer in its node.
  for_each_node(
      words, first, leaf_level, fail, [&](std::uint32_t l, std::uint64_t w, std::uint32_t header) {
        for (std::uint32_t stored = 0; stored < 8; ++stored) {
          if ((header >> stored & 1) == 0) continue;
          std::uint32_t mirror;
          const std::uint64_t p = child(w, l, stored, mirror);
          // A relative pointer may name a word before its level (or none: kSsvdagNoBase).
          const bool ok = l + 1 < leaf_level ? p >= first_[l + 1] && p < first_[l + 2] && starts[p]
                                             : p < leaves.size();
          if (!ok)
            fail("node at word " + std::to_string(w) + " has a child pointer to " +
                 std::to_string(p));
        }
      });
}

SsvdagView SsvdagView::from_blob(const Blob& blob, const std::string& name) {
  const StructureInfo* info = blob.structure(name);
  const auto* d = info ? structure_table(blob, *info).desc_as<schema::SsvdagDesc>() : nullptr;
  if (d == nullptr) blob.fail("has no SSVDAG '" + name + "'");
  // Blob::open checked the sections' kinds, sizes and counts and the level table's presence.
  std::vector<std::uint64_t> firsts;
  for (const auto* level : *d->level_stats()) firsts.push_back(level->first_word());
  if (!firsts.empty()) firsts.pop_back();  // the leaves' entry
  return SsvdagView(blob.section_view<std::uint16_t>(d->nodes()),
                    blob.section_view<std::uint64_t>(d->leaves()), grid_frame_of(*d), firsts,
                    d->root_mirror(), blob.name() + ": " + name);
}

std::uint64_t SsvdagView::child(std::uint64_t word, std::uint32_t level, std::uint32_t stored,
                                std::uint32_t& mirror) const {
  const bool to_leaves = level + 3 >= levels_;
  const std::uint64_t offset = format::ssvdag_child(&words_[word], stored, to_leaves, mirror);
  return to_leaves ? offset : first_[level + 1] + offset;
}

bool SsvdagView::occupied(const format::Float3& point) const {
  const auto cell = frame_.cell_of(point);
  return cell && occupied((*cell)[0], (*cell)[1], (*cell)[2]);
}

bool SsvdagView::occupied(std::uint32_t x, std::uint32_t y, std::uint32_t z) const {
  const std::uint32_t n = frame_.resolution;
  if (x >= n || y >= n || z >= n) return false;
  std::uint64_t word = 0;
  std::uint32_t mirror = root_mirror_;
  for (std::uint32_t l = 0; l + 2 < levels_; ++l) {
    const std::uint32_t shift = levels_ - 1 - l;
    const std::uint32_t octant = (x >> shift & 1) | (y >> shift & 1) << 1 | (z >> shift & 1) << 2;
    const std::uint32_t stored = octant ^ mirror;
    if ((words_[word] >> stored & 1) == 0) return false;
    std::uint32_t m;
    word = child(word, l, stored, m);
    mirror ^= m;
  }
  const std::uint32_t bit =
      format::morton_code(x & 3, y & 3, z & 3) ^ format::ssvdag_leaf_flip(mirror);
  return leaves_[word] >> bit & 1;
}

std::uint64_t SsvdagView::count_voxels() const {
  // Mirrors move voxels but never change how many: count each unique node once, bottom up.
  const std::uint32_t leaf_level = levels_ - 2;
  std::vector<std::uint64_t> below(leaves_.size()), current;
  for (std::size_t i = 0; i < leaves_.size(); ++i) below[i] = std::popcount(leaves_[i]);
  for (std::uint32_t l = leaf_level; l-- > 0;) {
    current.assign(first_[l + 1] - first_[l], 0);
    for (std::uint64_t w = first_[l]; w < first_[l + 1];) {
      const std::uint32_t header = words_[w];
      std::uint64_t sum = 0;
      for (std::uint32_t stored = 0; stored < 8; ++stored) {
        if ((header >> stored & 1) == 0) continue;
        std::uint32_t m;
        const std::uint64_t p = child(w, l, stored, m);
        sum += below[l + 1 < leaf_level ? p - first_[l + 1] : p];
      }
      current[w - first_[l]] = sum;
      w += 1 + std::popcount(header & 0xFF) + std::popcount(header >> 8);
    }
    below.swap(current);
  }
  return below[0];
}

}  // namespace kiln
