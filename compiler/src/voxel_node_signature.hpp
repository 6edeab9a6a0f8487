// An interior voxel node before layout, as the DAG and SSVDAG builders merge them: v[0] = child
// mask, v[1 + octant] = the child's reference (a DAG id, or for the SSVDAG a canonical
// id << 3 | mirror; absent children ~0), hashed to find equal nodes.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace kiln {

struct VoxelNodeSignature {
  std::array<std::uint32_t, 9> v;
  bool operator==(const VoxelNodeSignature&) const = default;
};

struct VoxelNodeSignatureHash {
  std::size_t operator()(const VoxelNodeSignature& s) const {
    std::uint64_t h = 0x9E3779B97F4A7C15ull;
    for (const std::uint32_t x : s.v) h = (h ^ x) * 0x100000001B3ull, h ^= h >> 29;
    return std::size_t(h);
  }
};

}  // namespace kiln
