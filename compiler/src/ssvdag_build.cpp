// Symmetry-aware sparse voxel DAG (Villanueva, Marton, Gobbetti 2016), reduced from the voxel DAG:
// bottom up over the DAG's unique nodes, every node is compared in its canonical form, the least
// of its eight mirror images. Working on the DAG rather than on every octree node keeps the cost
// with the DAG's size, so the SSVDAG goes wherever the (out-of-core) DAG build goes.
#include <algorithm>
#include <array>
#include <bit>
#include <numeric>
#include <stdexcept>
#include <unordered_map>

#include "kiln/compiler/ssvdag_builder.hpp"
#include "kiln/compiler/voxel_dag_builder.hpp"
#include "kiln/formats/ssvdag.hpp"
#include "kiln/runtime/parallel.hpp"
#include "voxel_node_signature.hpp"

namespace kiln {

namespace {

constexpr std::uint32_t kAbsent = ~0u;
constexpr std::size_t kBatch = 1024;

// A node before layout (voxel_node_signature.hpp); for the DAG count the references are plain
// DAG ids.
using Signature = VoxelNodeSignature;
using SignatureHash = VoxelNodeSignatureHash;

// The unique nodes of one level: canonical signatures (interior) or masks (leaves), and per node
// its symmetries (bit t: mirror t maps the node onto itself; bit 0 always).
struct UniqueLevel {
  std::vector<Signature> nodes;
  std::vector<std::uint64_t> leaves;
  std::vector<std::uint8_t> symmetries;
};

// One subtree has as many (id, mirror) names as its node has symmetries; the least mirror of the
// coset is the one name used, so that equal subtrees always have equal signatures.
std::uint32_t normalized(std::uint32_t mirror, std::uint8_t symmetries) {
  std::uint32_t best = mirror;
  for (std::uint32_t g = 1; g < 8; ++g)
    if (symmetries >> g & 1) best = std::min(best, mirror ^ g);
  return best;
}

std::uint32_t reference(std::uint32_t id, std::uint32_t mirror, std::uint8_t symmetries) {
  if (id >= format::kSsvdagWideOffsets) throw std::length_error("SSVDAG level exceeds 2^29 nodes");
  return id << 3 | normalized(mirror, symmetries);
}

// The node `s` mirrored by `t`: child o comes from octant o ^ t, itself mirrored by t.
Signature mirrored(const Signature& s, std::uint32_t t, std::span<const std::uint8_t> below) {
  Signature out;
  out.v[0] = format::ssvdag_mirror_mask(s.v[0], t);
  for (std::uint32_t o = 0; o < 8; ++o) {
    const std::uint32_t ref = s.v[1 + (o ^ t)];
    out.v[1 + o] =
        ref == kAbsent ? kAbsent : (ref & ~7u) | normalized((ref & 7) ^ t, below[ref >> 3]);
  }
  return out;
}

// How many pointers reach each node of each level (the root: none).
std::vector<std::vector<std::uint64_t>> reference_counts(const std::vector<UniqueLevel>& levels) {
  std::vector<std::vector<std::uint64_t>> counts(levels.size());
  counts[0] = {0};
  for (std::size_t l = 1; l < levels.size(); ++l) {
    counts[l].resize(levels[l].symmetries.size());
    for (const Signature& s : levels[l - 1].nodes)
      for (int o = 0; o < 8; ++o)
        if (s.v[1 + o] != kAbsent) ++counts[l][s.v[1 + o] >> 3];
  }
  return counts;
}

// A level's nodes in layout order: most pointers per word first, ties by id, as long as they
// start within the first `reach` words (absolute narrow pointers reach them); the paper orders by
// reference count, and dividing by the node's size packs more pointers into that window. The
// others follow in id order (first occurrence in Morton order), so that the children of a node
// and of its neighbours lie side by side, within a relative pointer's reach of each other.
std::vector<std::uint32_t> layout_order(std::span<const std::uint64_t> count,
                                        std::span<const std::uint64_t> size, std::uint64_t reach) {
  std::vector<std::uint32_t> order(count.size());
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
    return count[a] * size[b] > count[b] * size[a];
  });
  std::size_t hot = 0;
  for (std::uint64_t word = 0; hot < order.size() && word < reach;) word += size[order[hot++]];
  std::sort(order.begin() + std::ptrdiff_t(hot), order.end());
  return order;
}

// The words of one node whose children lie at `offsets` (of the level below; `to_leaves` from
// the last interior level): narrow absolute where the offset is within reach, else narrow
// relative to the node's first wide pointer where within reach of it, else wide.
void emit_node(const Signature& s, std::span<const std::uint64_t> offsets, bool to_leaves,
               const SsvdagPointerReach& reach, std::vector<std::uint16_t>& words,
               SsvdagLevelStats& stats) {
  const std::size_t header = words.size();
  words.push_back(0);
  std::uint32_t wide = 0;
  std::uint64_t base = 0;
  for (std::uint32_t o = 0; o < 8; ++o) {
    const std::uint32_t ref = s.v[1 + o];
    if (ref == kAbsent) continue;
    const std::uint64_t offset = offsets[ref >> 3];
    if (offset >= format::kSsvdagWideOffsets)
      throw std::length_error("SSVDAG level exceeds 2^29 words");
    const std::int64_t from_base = std::int64_t(offset) - std::int64_t(base);
    std::uint64_t x = offset;
    if (!to_leaves && offset >= reach.absolute && wide != 0 && from_base >= -reach.relative &&
        from_base < reach.relative)
      x = format::ssvdag_relative_x(offset, base), ++stats.relative_pointers;
    else if (offset >= (to_leaves ? reach.leaf : reach.absolute)) {
      if (wide == 0) base = offset;
      wide |= 1u << o;
    }
    const std::uint32_t value = std::uint32_t(x << 3) | (ref & 7);
    words.push_back(std::uint16_t(value));
    if (wide >> o & 1)
      words.push_back(std::uint16_t(value >> 16)), ++stats.wide_pointers;
    else
      ++stats.narrow_pointers;
  }
  words[header] = std::uint16_t(s.v[0] | wide << 8);
}

// Each node's size in words, its children lying at `offsets`.
std::vector<std::uint64_t> node_sizes(std::span<const Signature> nodes,
                                      std::span<const std::uint64_t> offsets, bool to_leaves,
                                      const SsvdagPointerReach& reach) {
  std::vector<std::uint64_t> size(nodes.size());
  std::vector<std::uint16_t> scratch;
  SsvdagLevelStats ignored;
  for (std::size_t id = 0; id < nodes.size(); ++id) {
    scratch.clear();
    emit_node(nodes[id], offsets, to_leaves, reach, scratch, ignored);
    size[id] = scratch.size();
  }
  return size;
}

// Layout: orders and offsets bottom up (a node's size depends on its children's offsets), then
// the words top down.
void lay_out(const std::vector<UniqueLevel>& levels, const SsvdagPointerReach& reach,
             FlatSsvdag& out) {
  const std::size_t leaf_level = levels.size() - 1;
  const auto counts = reference_counts(levels);
  std::vector<std::vector<std::uint64_t>> offsets(levels.size());
  std::vector<std::vector<std::uint32_t>> sequence(levels.size());
  sequence[leaf_level] =
      layout_order(counts[leaf_level], std::vector<std::uint64_t>(counts[leaf_level].size(), 1),
                   ~std::uint64_t(0));
  offsets[leaf_level].resize(sequence[leaf_level].size());
  for (std::uint32_t rank = 0; rank < sequence[leaf_level].size(); ++rank) {
    offsets[leaf_level][sequence[leaf_level][rank]] = rank;
    out.leaves.push_back(levels.back().leaves[sequence[leaf_level][rank]]);
  }
  for (std::size_t l = leaf_level; l-- > 0;) {
    const auto size = node_sizes(levels[l].nodes, offsets[l + 1], l + 1 == leaf_level, reach);
    sequence[l] = layout_order(counts[l], size, reach.absolute);
    offsets[l].resize(size.size());
    std::uint64_t word = 0;
    for (const std::uint32_t id : sequence[l]) offsets[l][id] = word, word += size[id];
  }
  for (std::size_t l = 0; l < leaf_level; ++l) {
    auto& stats = out.level_stats[l];
    stats.first_word = out.words.size();
    for (const std::uint32_t id : sequence[l])
      emit_node(levels[l].nodes[id], offsets[l + 1], l + 1 == leaf_level, reach, out.words, stats);
    stats.bytes = 2 * (out.words.size() - stats.first_word);
  }
  if (out.words.size() > 0xFFFFFFFFull) throw std::length_error("SSVDAG exceeds 2^32 words");
  out.level_stats[leaf_level].bytes = 8 * out.leaves.size();
  out.ssvdag_bytes = 2 * out.words.size() + 8 * out.leaves.size();
}

// The DAG's unique nodes per level, in id order: interior nodes with their children's ids in the
// level below, and the leaves' masks.
struct DagNodes {
  std::vector<std::vector<Signature>> interior;  // levels 0 .. leaf level - 1
  std::vector<std::uint64_t> leaves;
};

// Each node's first word, level by level (nodes are laid out back to back in id order).
std::vector<std::vector<std::uint64_t>> node_starts(const FlatVoxelDag& dag) {
  const std::uint32_t leaf_level = dag.levels - 2;
  std::vector<std::vector<std::uint64_t>> starts(leaf_level);
  for (std::uint32_t l = 0; l < leaf_level; ++l) {
    const std::uint64_t end =
        l + 1 < leaf_level ? dag.level_stats[l + 1].first_word : dag.leaf_first_word;
    for (std::uint64_t w = dag.level_stats[l].first_word; w < end;
         w += 1 + std::popcount(dag.words[w]))
      starts[l].push_back(w);
  }
  return starts;
}

DagNodes read_dag(const FlatVoxelDag& dag) {
  const std::uint32_t leaf_level = dag.levels - 2;
  const auto& w = dag.words;
  DagNodes out;
  for (std::uint64_t i = dag.leaf_first_word; i + 1 < w.size(); i += 2)
    out.leaves.push_back(w[i] | std::uint64_t(w[i + 1]) << 32);
  const auto starts = node_starts(dag);
  out.interior.resize(leaf_level);
  for (std::uint32_t l = 0; l < leaf_level; ++l)
    for (const std::uint64_t first : starts[l]) {
      Signature s;
      s.v.fill(kAbsent);
      s.v[0] = w[first];
      std::uint64_t at = first + 1;
      for (std::uint32_t o = 0; o < 8; ++o) {
        if ((s.v[0] >> o & 1) == 0) continue;
        const std::uint64_t child = w[at++];
        s.v[1 + o] = l + 1 < leaf_level
                         ? std::uint32_t(
                               std::lower_bound(starts[l + 1].begin(), starts[l + 1].end(), child) -
                               starts[l + 1].begin())
                         : std::uint32_t((child - dag.leaf_first_word) / 2);
      }
      out.interior[l].push_back(s);
    }
  return out;
}

// The leaves' canonical masks on `threads` threads, then ids in DAG id order; returns each DAG
// leaf's SSVDAG reference.
std::vector<std::uint32_t> merge_dag_leaves(std::span<const std::uint64_t> masks,
                                            UniqueLevel& unique, unsigned threads) {
  const std::size_t n = masks.size();
  std::vector<std::uint64_t> canonical(n);
  std::vector<std::uint8_t> mirror(n);
  parallel_for_batched(n, kBatch, threads, [&](std::size_t i) {
    std::uint64_t best = masks[i];
    for (std::uint32_t t = 1; t < 8; ++t)
      if (const std::uint64_t m = format::ssvdag_mirror_leaf(masks[i], t); m < best)
        best = m, mirror[i] = std::uint8_t(t);
    canonical[i] = best;
  });
  std::vector<std::uint32_t> refs(n);
  std::unordered_map<std::uint64_t, std::uint32_t> ids;
  for (std::size_t i = 0; i < n; ++i) {
    const auto [it, fresh] = ids.emplace(canonical[i], std::uint32_t(unique.leaves.size()));
    if (fresh) {
      std::uint8_t symmetries = 0;
      for (std::uint32_t t = 0; t < 8; ++t)
        if (format::ssvdag_mirror_leaf(canonical[i], t) == canonical[i]) symmetries |= 1u << t;
      unique.leaves.push_back(canonical[i]);
      unique.symmetries.push_back(symmetries);
    }
    refs[i] = reference(it->second, mirror[i], unique.symmetries[it->second]);
  }
  return refs;
}

// One interior level: each DAG node's children become the level below's references, the node
// its canonical form, and equal canonical forms merge (ids in DAG id order). Returns each DAG
// node's SSVDAG reference.
std::vector<std::uint32_t> merge_dag_level(std::span<const Signature> nodes,
                                           std::span<const std::uint32_t> below_refs,
                                           std::span<const std::uint8_t> below_symmetries,
                                           UniqueLevel& unique, unsigned threads) {
  const std::size_t n = nodes.size();
  std::vector<Signature> canonical(n);
  std::vector<std::uint8_t> mirror(n);
  parallel_for_batched(n, kBatch, threads, [&](std::size_t j) {
    Signature s = nodes[j];
    for (std::uint32_t o = 0; o < 8; ++o)
      if (s.v[1 + o] != kAbsent) s.v[1 + o] = below_refs[s.v[1 + o]];
    Signature best = s;
    for (std::uint32_t t = 1; t < 8; ++t)
      if (const Signature m = mirrored(s, t, below_symmetries); m.v < best.v)
        best = m, mirror[j] = std::uint8_t(t);
    canonical[j] = best;
  });
  std::vector<std::uint32_t> refs(n);
  std::unordered_map<Signature, std::uint32_t, SignatureHash> ids;
  for (std::size_t j = 0; j < n; ++j) {
    const Signature& c = canonical[j];
    const auto [it, fresh] = ids.emplace(c, std::uint32_t(unique.nodes.size()));
    if (fresh) {
      std::uint8_t symmetries = 1;
      for (std::uint32_t t = 1; t < 8; ++t)
        if (mirrored(c, t, below_symmetries) == c) symmetries |= 1u << t;
      unique.nodes.push_back(c);
      unique.symmetries.push_back(symmetries);
    }
    refs[j] = reference(it->second, mirror[j], unique.symmetries[it->second]);
  }
  return refs;
}

}  // namespace

FlatSsvdag build_ssvdag(const FlatVoxelDag& dag, unsigned threads,
                        const SsvdagPointerReach& reach) {
  if (reach.leaf > format::kSsvdagNarrowOffsets ||
      reach.absolute > format::kSsvdagAbsoluteOffsets ||
      reach.relative > format::kSsvdagRelativeReach || reach.relative < 0)
    throw std::invalid_argument("SSVDAG pointer reach beyond the format's");
  FlatSsvdag out;
  out.levels = dag.levels;
  out.voxel_count = dag.voxel_count;
  out.svo_bytes = dag.svo_bytes;
  out.dag_bytes = dag.dag_bytes;
  const std::uint32_t leaf_level = out.levels - 2;
  out.level_stats.resize(leaf_level + 1);
  std::vector<UniqueLevel> levels(leaf_level + 1);
  DagNodes nodes = read_dag(dag);
  std::vector<std::uint32_t> refs = merge_dag_leaves(nodes.leaves, levels[leaf_level], threads);
  for (std::uint32_t l = leaf_level + 1; l-- > 0;) {
    if (l < leaf_level) {
      refs = merge_dag_level(nodes.interior[l], refs, levels[l + 1].symmetries, levels[l], threads);
      std::vector<Signature>().swap(nodes.interior[l]);
    }
    auto& stats = out.level_stats[l];
    stats.svo_nodes = dag.level_stats[l].svo_nodes;
    stats.dag_nodes = dag.level_stats[l].dag_nodes;
    stats.ssvdag_nodes = l < leaf_level ? levels[l].nodes.size() : levels[l].leaves.size();
  }
  out.root_mirror = refs.at(0) & 7;
  for (const auto& s : out.level_stats) out.symmetry_merges += s.dag_nodes - s.ssvdag_nodes;
  lay_out(levels, reach, out);
  return out;
}

FlatSsvdag build_ssvdag(std::span<const std::uint64_t> codes, std::uint32_t resolution,
                        unsigned threads, const SsvdagPointerReach& reach) {
  return build_ssvdag(leaves_of(codes), resolution, threads, reach);
}

FlatSsvdag build_ssvdag(const VoxelLeaves& leaves, std::uint32_t resolution, unsigned threads,
                        const SsvdagPointerReach& reach) {
  if (leaves.keys.empty()) throw std::invalid_argument("an SSVDAG needs at least one voxel");
  return build_ssvdag(build_voxel_dag(leaves, resolution), threads, reach);
}

std::vector<std::uint64_t> ssvdag_level_first_words(const FlatSsvdag& ssvdag) {
  std::vector<std::uint64_t> firsts;
  for (std::size_t l = 0; l + 1 < ssvdag.level_stats.size(); ++l)
    firsts.push_back(ssvdag.level_stats[l].first_word);
  return firsts;
}

std::vector<std::uint64_t> expand_ssvdag(const FlatSsvdag& ssvdag) {
  const std::uint32_t leaf_level = ssvdag.levels - 2;
  const auto firsts = ssvdag_level_first_words(ssvdag);
  std::vector<std::uint64_t> codes;
  struct Pending {
    std::uint64_t word;
    std::uint32_t level, mirror;
    std::uint64_t key;
  };
  std::vector<Pending> stack{{0, 0, ssvdag.root_mirror, 0}};
  while (!stack.empty()) {
    const Pending p = stack.back();
    stack.pop_back();
    if (p.level == leaf_level) {
      const std::uint64_t leaf = format::ssvdag_mirror_leaf(ssvdag.leaves[p.word], p.mirror);
      for (std::uint32_t bit = 0; bit < 64; ++bit)
        if (leaf >> bit & 1) codes.push_back(p.key << 6 | bit);
      continue;
    }
    const std::uint32_t header = ssvdag.words[p.word];
    for (std::uint32_t stored = 0; stored < 8; ++stored) {
      if ((header >> stored & 1) == 0) continue;
      std::uint32_t mirror;
      const bool to_leaves = p.level + 1 == leaf_level;
      const std::uint64_t offset =
          format::ssvdag_child(&ssvdag.words[p.word], stored, to_leaves, mirror);
      stack.push_back({to_leaves ? offset : firsts[p.level + 1] + offset, p.level + 1,
                       p.mirror ^ mirror, p.key << 3 | (stored ^ p.mirror)});
    }
  }
  std::sort(codes.begin(), codes.end());
  return codes;
}

}  // namespace kiln
