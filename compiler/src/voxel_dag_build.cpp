#include <algorithm>
#include <array>
#include <bit>
#include <stdexcept>
#include <string>

#include "kiln/compiler/voxel_dag_builder.hpp"
#include "kiln/formats/voxel_grid.hpp"
#include "voxel_dag_reducer.hpp"

namespace kiln {

template <class Value, class Hash>
std::uint32_t UniqueValues<Value, Hash>::insert(const Value& value) {
  if (2 * (values_.size() + 1) > slots_.size()) grow();
  const std::size_t mask = slots_.size() - 1;
  for (std::size_t slot = Hash{}(value)&mask;; slot = (slot + 1) & mask) {
    const std::uint32_t id = slots_[slot];
    if (id == 0) {
      if (values_.size() >= 0xFFFFFFFEull)
        throw std::length_error("voxel DAG: more than 2^32 nodes on one level");
      values_.push_back(value);
      slots_[slot] = std::uint32_t(values_.size());
      return std::uint32_t(values_.size() - 1);
    }
    if (values_[id - 1] == value) return id - 1;
  }
}

template <class Value, class Hash>
void UniqueValues<Value, Hash>::grow() {
  std::vector<std::uint32_t> slots(std::max<std::size_t>(64, 2 * slots_.size()), 0);
  const std::size_t mask = slots.size() - 1;
  for (std::size_t id = 0; id < values_.size(); ++id) {
    std::size_t slot = Hash{}(values_[id]) & mask;
    while (slots[slot] != 0) slot = (slot + 1) & mask;
    slots[slot] = std::uint32_t(id + 1);
  }
  slots_.swap(slots);
}

VoxelDagReducer::VoxelDagReducer(std::uint32_t resolution) {
  if (resolution < 8 || (resolution & (resolution - 1)) != 0)
    throw std::invalid_argument("voxel DAG resolution " + std::to_string(resolution) +
                                " is not a power of two >= 8");
  levels_ = std::uint32_t(std::bit_width(resolution) - 1);
  leaf_level_ = levels_ - 2;
  nodes_.resize(leaf_level_);
  stats_.levels = levels_;
  stats_.level_stats.resize(leaf_level_ + 1);
}

std::uint32_t VoxelDagReducer::level_of_side(std::uint32_t side) const {
  return levels_ - std::uint32_t(std::bit_width(side) - 1);
}

// Words may only be addressed by 32-bit pointers: refuse as soon as the unique nodes pass that,
// not after the whole build.
void VoxelDagReducer::count_words(std::uint64_t words) {
  words_ += words;
  if (words_ > 0xFFFFFFFFull)
    throw std::length_error(
        "voxel DAG exceeds 2^32 words (16 GiB), the limit of its 32-bit child pointers");
}

// Leaves: 64-bit masks of 4x4x4 blocks, merged by value.
VoxelDagReducer::Level VoxelDagReducer::merge_leaves(const VoxelLeaves& leaves) {
  Level below;
  below.keys = leaves.keys;
  below.ids.reserve(leaves.keys.size());
  for (const std::uint64_t mask : leaves.masks) {
    const std::size_t before = leaves_.values().size();
    below.ids.push_back(leaves_.insert(mask));
    if (leaves_.values().size() != before) count_words(2);
  }
  auto& s = stats_.level_stats[leaf_level_];
  s.svo_nodes += leaves.keys.size();
  stats_.svo_bytes += 8 * leaves.keys.size();
  stats_.voxel_count += leaves.voxel_count;
  return below;
}

std::uint32_t VoxelDagReducer::insert_node(std::uint32_t level, const VoxelNodeSignature& s) {
  const std::size_t before = nodes_[level].values().size();
  const std::uint32_t id = nodes_[level].insert(s);
  if (nodes_[level].values().size() != before) count_words(1 + std::popcount(s.v[0]));
  stats_.level_stats[level].svo_nodes += 1;
  stats_.svo_bytes += 4 * (1 + std::popcount(s.v[0]));
  return id;
}

std::uint32_t VoxelDagReducer::add_node(std::uint32_t level, const std::uint32_t (&children)[8]) {
  VoxelNodeSignature s;
  s.v.fill(~0u);
  s.v[0] = 0;
  for (int octant = 0; octant < 8; ++octant)
    if (children[octant] != kEmpty) s.v[0] |= 1u << octant, s.v[1 + octant] = children[octant];
  return s.v[0] == 0 ? kEmpty : insert_node(level, s);
}

// One interior level from the level below it: siblings (same key >> 3) form a signature.
VoxelDagReducer::Level VoxelDagReducer::merge_level(std::uint32_t level, const Level& below) {
  Level current;
  for (std::size_t i = 0; i < below.keys.size();) {
    const std::uint64_t key = below.keys[i] >> 3;
    std::uint32_t children[8];
    std::fill(std::begin(children), std::end(children), kEmpty);
    for (; i < below.keys.size() && below.keys[i] >> 3 == key; ++i)
      children[below.keys[i] & 7] = below.ids[i];
    current.keys.push_back(key);
    current.ids.push_back(add_node(level, children));
  }
  return current;
}

std::uint32_t VoxelDagReducer::add_cube(const VoxelLeaves& leaves, const VoxelCube& cube) {
  if (leaves.keys.empty()) return kEmpty;
  const std::uint32_t top = level_of_side(cube.side);
  // Every leaf key must lie in the cube: its key at the cube's level is the cube's.
  const std::uint64_t cube_key =
      format::morton_code(cube.origin[0], cube.origin[1], cube.origin[2]) >> 3 * (levels_ - top);
  const auto outside = [&](std::uint64_t key) {
    return key >> 3 * (leaf_level_ - top) != cube_key;
  };
  if (outside(leaves.keys.front()) || outside(leaves.keys.back()) ||
      !std::is_sorted(leaves.keys.begin(), leaves.keys.end()))
    throw std::invalid_argument("voxel codes lie outside the grid");
  Level below = merge_leaves(leaves);
  for (std::uint32_t level = leaf_level_; level-- > top;) below = merge_level(level, below);
  return below.ids.front();
}

std::uint64_t VoxelDagReducer::bytes() const {
  std::uint64_t total = leaves_.bytes();
  for (const auto& level : nodes_) total += level.bytes();
  return total;
}

namespace {

// Layout: levels top down, then the leaf masks; pointers are absolute word indices. Fills
// `dag.words`, the first words and byte counts.
void lay_out(const std::vector<const std::vector<VoxelNodeSignature>*>& unique,
             const std::vector<std::uint64_t>& leaf_masks, FlatVoxelDag& dag) {
  const auto leaf_level = std::uint32_t(unique.size());
  std::vector<std::vector<std::uint32_t>> offsets(leaf_level);  // word of each node in its level
  std::uint64_t word = 0;
  for (std::uint32_t level = 0; level < leaf_level; ++level) {
    dag.level_stats[level].first_word = word;
    offsets[level].reserve(unique[level]->size());
    for (const VoxelNodeSignature& s : *unique[level]) {
      offsets[level].push_back(std::uint32_t(word));
      word += 1 + std::popcount(s.v[0]);
    }
    dag.level_stats[level].bytes = 4 * (word - dag.level_stats[level].first_word);
  }
  dag.leaf_first_word = word;
  dag.level_stats[leaf_level].first_word = word;
  word += 2 * leaf_masks.size();
  if (word > 0xFFFFFFFFull) throw std::length_error("voxel DAG exceeds 2^32 words");
  dag.words.reserve(word);
  for (std::uint32_t level = 0; level < leaf_level; ++level)
    for (const VoxelNodeSignature& s : *unique[level]) {
      dag.words.push_back(s.v[0]);
      for (int octant = 0; octant < 8; ++octant) {
        if ((s.v[0] >> octant & 1) == 0) continue;
        const std::uint32_t child = s.v[1 + octant];
        dag.words.push_back(std::uint32_t(level + 1 < leaf_level
                                              ? offsets[level + 1][child]
                                              : dag.leaf_first_word + 2 * std::uint64_t(child)));
      }
    }
  for (const std::uint64_t mask : leaf_masks) {
    dag.words.push_back(std::uint32_t(mask));
    dag.words.push_back(std::uint32_t(mask >> 32));
  }
  dag.dag_bytes = 4 * dag.words.size();
}

}  // namespace

FlatVoxelDag VoxelDagReducer::finish(std::uint32_t root) {
  if (root == kEmpty) throw std::invalid_argument("a voxel DAG needs at least one voxel");
  FlatVoxelDag dag = std::move(stats_);
  std::vector<const std::vector<VoxelNodeSignature>*> unique;
  for (std::uint32_t level = 0; level < leaf_level_; ++level) {
    unique.push_back(&nodes_[level].values());
    dag.level_stats[level].dag_nodes = nodes_[level].values().size();
  }
  auto& leaf = dag.level_stats[leaf_level_];
  leaf.dag_nodes = leaves_.values().size();
  leaf.bytes = 8 * leaf.dag_nodes;
  lay_out(unique, leaves_.values(), dag);
  return dag;
}

FlatVoxelDag build_voxel_dag(std::span<const std::uint64_t> codes, std::uint32_t resolution) {
  return build_voxel_dag(leaves_of(codes), resolution);
}

FlatVoxelDag build_voxel_dag(const VoxelLeaves& leaves, std::uint32_t resolution) {
  if (leaves.keys.empty()) throw std::invalid_argument("a voxel DAG needs at least one voxel");
  VoxelDagReducer reducer(resolution);
  return reducer.finish(reducer.add_cube(leaves, VoxelCube{{0, 0, 0}, resolution}));
}

std::vector<std::uint64_t> expand_voxel_dag(std::span<const std::uint32_t> words,
                                            std::uint32_t levels) {
  std::vector<std::uint64_t> codes;
  struct Pending {
    std::uint32_t word, level;
    std::uint64_t key;
  };
  std::vector<Pending> stack{{0, 0, 0}};
  while (!stack.empty()) {
    const Pending p = stack.back();
    stack.pop_back();
    if (p.level == levels - 2) {
      const std::uint64_t mask = words[p.word] | std::uint64_t(words[p.word + 1]) << 32;
      for (int bit = 0; bit < 64; ++bit)
        if (mask >> bit & 1) codes.push_back(p.key << 6 | std::uint64_t(bit));
      continue;
    }
    const std::uint32_t mask = words[p.word];
    std::uint32_t next = p.word + 1;
    for (int octant = 0; octant < 8; ++octant)
      if (mask >> octant & 1)
        stack.push_back({words[next++], p.level + 1, p.key << 3 | std::uint64_t(octant)});
  }
  std::sort(codes.begin(), codes.end());
  return codes;
}

}  // namespace kiln
