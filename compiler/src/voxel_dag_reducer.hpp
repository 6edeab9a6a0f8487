// The voxel DAG's reduction, fed piece by piece: one table of unique nodes per level (Kampe,
// Sintorn, Assarsson 2013, section 4: sub-DAGs merged through global per-level hash tables). The
// in-core build feeds it the whole grid as one cube; the out-of-core build feeds it sub-cubes in
// Morton order and then the nodes above them. Ids are assigned in order of first occurrence,
// so as long as every level's nodes arrive in Morton order the words do not depend on how the
// grid was cut.
#pragma once

#include <cstdint>
#include <vector>

#include "kiln/compiler/voxel_dag_builder.hpp"
#include "kiln/compiler/voxelizer.hpp"
#include "voxel_node_signature.hpp"

namespace kiln {

// Distinct values in order of first insertion; open addressing over ids (4 bytes a slot), so
// the memory is the values plus a few bytes each, and no iteration order ever reaches output.
template <class Value, class Hash>
class UniqueValues {
 public:
  // The id of `value`, inserting it when new.
  std::uint32_t insert(const Value& value);
  const std::vector<Value>& values() const { return values_; }
  std::uint64_t bytes() const { return values_.capacity() * sizeof(Value) + 4 * slots_.size(); }

 private:
  void grow();
  std::vector<Value> values_;
  std::vector<std::uint32_t> slots_;  // id + 1; 0 = empty
};

struct MaskHash {
  std::size_t operator()(std::uint64_t x) const {
    x ^= x >> 31, x *= 0x7FB5D329728EA185ull, x ^= x >> 27, x *= 0x81DADEF4BC2DD44Dull;
    return std::size_t(x ^ x >> 33);
  }
};

class VoxelDagReducer {
 public:
  static constexpr std::uint32_t kEmpty = ~0u;

  explicit VoxelDagReducer(std::uint32_t resolution);
  std::uint32_t levels() const { return levels_; }
  // The level whose nodes are cubes of `side` voxels (the root's level is 0).
  std::uint32_t level_of_side(std::uint32_t side) const;

  // Reduces the leaves of one cube (keys ascending, all inside it; empty: kEmpty) to the id of
  // the cube's node at its level. Throws std::invalid_argument when a key lies outside it.
  std::uint32_t add_cube(const VoxelLeaves& leaves, const VoxelCube& cube);
  // The node at `level` whose present octants (bit c of the mask) have the given child ids.
  std::uint32_t add_node(std::uint32_t level, const std::uint32_t (&children)[8]);
  // Lays the levels out below the root (the id add_cube or add_node returned at level 0).
  FlatVoxelDag finish(std::uint32_t root);
  // Memory held by the tables (unique nodes), bytes.
  std::uint64_t bytes() const;

 private:
  struct Level {
    std::vector<std::uint64_t> keys;
    std::vector<std::uint32_t> ids;
  };
  Level merge_leaves(const VoxelLeaves& leaves);
  Level merge_level(std::uint32_t level, const Level& below);
  std::uint32_t insert_node(std::uint32_t level, const VoxelNodeSignature& s);
  void count_words(std::uint64_t words);

  std::uint32_t levels_ = 0, leaf_level_ = 0;
  std::vector<UniqueValues<VoxelNodeSignature, VoxelNodeSignatureHash>> nodes_;  // per level
  UniqueValues<std::uint64_t, MaskHash> leaves_;
  FlatVoxelDag stats_;       // counts and level stats so far, no words
  std::uint64_t words_ = 0;  // words of the unique nodes so far
};

}  // namespace kiln
