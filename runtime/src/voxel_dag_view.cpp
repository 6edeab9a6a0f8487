#include <algorithm>
#include <bit>
#include <string>
#include <vector>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/voxel_dag.hpp"
#include "voxel_grid_frame.hpp"

namespace kiln {

VoxelDagView::VoxelDagView(std::span<const std::uint32_t> words, const VoxelGridFrame& frame,
                           std::span<const std::uint64_t> level_first_words,
                           std::uint64_t leaf_first_word, std::span<const std::uint64_t> codes,
                           std::span<const std::uint32_t> normals, const std::string& name)
    : words_(words), frame_(frame), codes_(codes), normals_(normals) {
  auto fail = [&](const std::string& what) { throw BlobError(name + ": " + what); };
  if (const std::string problem = grid_frame_problem(frame, format::kVoxelMaxResolution);
      !problem.empty())
    fail(problem);
  const std::uint32_t n = frame.resolution;
  levels_ = std::uint32_t(std::bit_width(n) - 1);
  const std::uint32_t leaf_level = levels_ - 2;
  if (level_first_words.size() != leaf_level + 1)
    fail(std::to_string(level_first_words.size()) + " levels, expected " +
         std::to_string(leaf_level + 1));
  if (level_first_words[0] != 0 || level_first_words[leaf_level] != leaf_first_word ||
      leaf_first_word >= words.size() || (words.size() - leaf_first_word) % 2 != 0)
    fail("level or leaf offsets out of range");
  for (std::uint32_t l = 0; l < leaf_level; ++l)
    if (level_first_words[l] >= level_first_words[l + 1])
      fail("level " + std::to_string(l) + " is empty or out of order");
  if (codes.size() != normals.size()) fail("voxel codes and normals differ in count");

  // Parse every interior level: node starts, masks of at most 8 bits, nodes inside their level.
  std::vector<bool> starts(leaf_first_word);
  for (std::uint32_t l = 0; l < leaf_level; ++l)
    for (std::uint64_t w = level_first_words[l], end = level_first_words[l + 1]; w < end;) {
      const std::uint32_t mask = words[w];
      if (mask == 0 || mask > 0xFF)
        fail("word " + std::to_string(w) + " is not a node header (mask " + std::to_string(mask) +
             ")");
      const std::uint64_t size = 1 + std::popcount(mask);
      if (size > end - w) fail("node at word " + std::to_string(w) + " overruns its level");
      if (l == 0 && end != size) fail("level 0 holds more than the root");
      starts[w] = true;
      w += size;
    }
  // Every pointer names a node of the next level, or a leaf mask from the last interior level.
  for (std::uint32_t l = 0; l < leaf_level; ++l)
    for (std::uint64_t w = level_first_words[l], end = level_first_words[l + 1]; w < end;) {
      const std::uint64_t count = std::popcount(words[w]);
      for (std::uint64_t i = 1; i <= count; ++i) {
        const std::uint64_t p = words[w + i];
        const bool ok =
            l + 1 < leaf_level
                ? p >= level_first_words[l + 1] && p < level_first_words[l + 2] && starts[p]
                : p >= leaf_first_word && (p - leaf_first_word) % 2 == 0 && p + 1 < words.size();
        if (!ok)
          fail("node at word " + std::to_string(w) + " has a child pointer to word " +
               std::to_string(p));
      }
      w += 1 + count;
    }
}

VoxelDagView VoxelDagView::from_blob(const Blob& blob, const std::string& name) {
  const StructureInfo* info = blob.structure(name);
  const auto* d = info ? structure_table(blob, *info).desc_as<schema::VoxelDagDesc>() : nullptr;
  if (d == nullptr) blob.fail("has no voxel DAG '" + name + "'");
  // Blob::open checked kinds, sizes and counts of these sections, and the level table's presence.
  std::vector<std::uint64_t> firsts;
  for (const auto* level : *d->level_stats()) firsts.push_back(level->first_word());
  return VoxelDagView(blob.section_view<std::uint32_t>(d->words()), grid_frame_of(*d), firsts,
                      d->leaf_first_word(), blob.section_view<std::uint64_t>(d->voxel_codes()),
                      blob.section_view<std::uint32_t>(d->voxel_normals()),
                      blob.name() + ": " + name);
}

bool VoxelDagView::occupied(const format::Float3& point) const {
  const auto cell = frame_.cell_of(point);
  return cell && occupied((*cell)[0], (*cell)[1], (*cell)[2]);
}

bool VoxelDagView::occupied(std::uint32_t x, std::uint32_t y, std::uint32_t z) const {
  const std::uint32_t n = frame_.resolution;
  if (x >= n || y >= n || z >= n) return false;
  std::uint32_t word = 0;
  for (std::uint32_t l = 0; l + 2 < levels_; ++l) {
    const std::uint32_t shift = levels_ - 1 - l;
    const std::uint32_t octant = (x >> shift & 1) | (y >> shift & 1) << 1 | (z >> shift & 1) << 2;
    const std::uint32_t mask = words_[word];
    if ((mask >> octant & 1) == 0) return false;
    word = words_[word + 1 + std::popcount(mask & ((1u << octant) - 1))];
  }
  const std::uint64_t leaf = words_[word] | std::uint64_t(words_[word + 1]) << 32;
  return leaf >> format::morton_code(x & 3, y & 3, z & 3) & 1;
}

bool VoxelDagView::attached_normal(std::uint32_t x, std::uint32_t y, std::uint32_t z,
                                   float n[3]) const {
  const std::uint64_t code = format::morton_code(x, y, z);
  const auto it = std::lower_bound(codes_.begin(), codes_.end(), code);
  if (it == codes_.end() || *it != code) return false;
  format::decode_octahedral(normals_[std::size_t(it - codes_.begin())], n);
  return true;
}

}  // namespace kiln
