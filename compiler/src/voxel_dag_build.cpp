#include <algorithm>
#include <array>
#include <bit>
#include <stdexcept>
#include <unordered_map>

#include "kiln/compiler/voxel_dag_builder.hpp"
#include "voxel_node_signature.hpp"

namespace kiln {

namespace {

using Signature = VoxelNodeSignature;
using SignatureHash = VoxelNodeSignatureHash;

// One level of the plain octree, in Morton order: each node's key and its DAG id.
struct Level {
  std::vector<std::uint64_t> keys;
  std::vector<std::uint32_t> ids;
};

// Leaves: 64-bit masks of 4x4x4 blocks, merged by value. Returns the unique masks in order of
// first occurrence; `below` gets every leaf's key and mask id, `dag` the leaf level's stats.
std::vector<std::uint64_t> merge_leaves(const VoxelLeaves& leaves, std::uint32_t leaf_level,
                                        Level& below, FlatVoxelDag& dag) {
  std::vector<std::uint64_t> leaf_masks;
  std::unordered_map<std::uint64_t, std::uint32_t> ids;
  for (std::size_t i = 0; i < leaves.keys.size(); ++i) {
    const std::uint64_t mask = leaves.masks[i];
    const auto [it, fresh] = ids.emplace(mask, std::uint32_t(leaf_masks.size()));
    if (fresh) leaf_masks.push_back(mask);
    below.keys.push_back(leaves.keys[i]);
    below.ids.push_back(it->second);
  }
  auto& s = dag.level_stats[leaf_level];
  s.svo_nodes = below.keys.size();
  s.dag_nodes = leaf_masks.size();
  s.bytes = 8 * leaf_masks.size();
  dag.svo_bytes += 8 * below.keys.size();
  return leaf_masks;
}

// One interior level from the level `below` it: siblings (same key >> 3) form a signature, and
// equal signatures merge. Appends the new unique signatures to `unique` (ids index it) and adds
// the plain octree's bytes for this level to `svo_bytes`.
Level merge_level(const Level& below, std::vector<Signature>& unique, std::uint64_t& svo_bytes) {
  Level current;
  std::unordered_map<Signature, std::uint32_t, SignatureHash> ids;
  for (std::size_t i = 0; i < below.keys.size();) {
    const std::uint64_t key = below.keys[i] >> 3;
    Signature sig;
    sig.v.fill(~0u);
    sig.v[0] = 0;
    for (; i < below.keys.size() && below.keys[i] >> 3 == key; ++i) {
      const auto octant = below.keys[i] & 7;
      sig.v[0] |= 1u << octant;
      sig.v[1 + octant] = below.ids[i];
    }
    svo_bytes += 4 * (1 + std::popcount(sig.v[0]));
    const auto [it, fresh] = ids.emplace(sig, std::uint32_t(unique.size()));
    if (fresh) unique.push_back(sig);
    current.keys.push_back(key);
    current.ids.push_back(it->second);
  }
  return current;
}

// Layout: levels top down, then the leaf masks; pointers are absolute word indices. Fills
// `dag.words`, the first words and byte counts.
void lay_out(const std::vector<std::vector<Signature>>& unique,
             const std::vector<std::uint64_t>& leaf_masks, FlatVoxelDag& dag) {
  const auto leaf_level = std::uint32_t(unique.size());
  std::vector<std::vector<std::uint64_t>> offsets(leaf_level);  // word of each node in its level
  std::uint64_t word = 0;
  for (std::uint32_t level = 0; level < leaf_level; ++level) {
    dag.level_stats[level].first_word = word;
    for (const Signature& s : unique[level]) {
      offsets[level].push_back(word);
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
    for (const Signature& s : unique[level]) {
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

FlatVoxelDag build_voxel_dag(std::span<const std::uint64_t> codes, std::uint32_t resolution) {
  return build_voxel_dag(leaves_of(codes), resolution);
}

FlatVoxelDag build_voxel_dag(const VoxelLeaves& leaves, std::uint32_t resolution) {
  if (leaves.keys.empty()) throw std::invalid_argument("a voxel DAG needs at least one voxel");
  FlatVoxelDag dag;
  dag.levels = std::uint32_t(std::bit_width(resolution) - 1);
  dag.voxel_count = leaves.voxel_count;
  const std::uint32_t leaf_level = dag.levels - 2;
  dag.level_stats.resize(leaf_level + 1);

  Level below;
  const std::vector<std::uint64_t> leaf_masks = merge_leaves(leaves, leaf_level, below, dag);
  // Interior levels, bottom up.
  std::vector<std::vector<Signature>> unique(leaf_level);
  for (std::uint32_t level = leaf_level; level-- > 0;) {
    below = merge_level(below, unique[level], dag.svo_bytes);
    dag.level_stats[level].svo_nodes = below.keys.size();
    dag.level_stats[level].dag_nodes = unique[level].size();
  }
  if (below.keys.size() != 1 || below.keys[0] != 0)
    throw std::invalid_argument("voxel codes lie outside the grid");
  lay_out(unique, leaf_masks, dag);
  return dag;
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
