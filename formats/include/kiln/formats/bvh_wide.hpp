// On-disk layout of the wide BVH (kinds bvh and sbvh with width 4, 8 or 16): one arena of wide
// nodes whose child boxes are stored structure-of-arrays (one SIMD slab test covers every child),
// each followed by the triangle packets of its leaf children (four triangles per packet,
// structure-of-arrays, with their primitive ids), so that a node and its leaves share cache lines
// and memory pages. The bytes do not depend on the CPU that built or reads them; the runtime
// picks a kernel (scalar, SSE, AVX2, AVX-512).
#pragma once

#include <cstddef>
#include <cstdint>

#include "kiln/formats/bvh.hpp"
#include "kiln/formats/container.hpp"

namespace kiln::format {

/// The wide BVH's arena: nodes and leaf packets in 16-byte units (see BvhWideNode).
inline constexpr std::uint32_t kSectionBvhWideArena = fourcc('B', 'V', 'W', 'A');
/// The sections of the layout before the arena (nodes, packets and, in BVHP, one primitive id
/// per lane, apart): no longer written; a reader refuses such a BVH with a message to rebuild it.
inline constexpr std::uint32_t kSectionBvhWideNodes = fourcc('B', 'V', 'W', 'N');
inline constexpr std::uint32_t kSectionBvhPackets = fourcc('B', 'V', 'W', 'T');
inline constexpr std::uint32_t kSectionBvhQuantizedNodes = fourcc('B', 'V', 'Q', 'N');

/// Arena offsets count units of this many bytes.
inline constexpr std::uint32_t kBvhArenaUnit = 16;
/// Nodes start on cache lines of this many bytes (as do the node's interior children).
inline constexpr std::uint32_t kBvhArenaLine = 64;

/// Triangles per leaf packet (SIMD lanes of the triangle test).
inline constexpr std::uint32_t kBvhPacketSize = 4;
/// Set in a child word when the child is a leaf; the other bits are its first packet.
inline constexpr std::uint32_t kBvhLeafFlag = 0x80000000u;

/// A wide node of W children (W = 4, 8 or 16), stored in the arena at a 64-byte boundary. The arena
/// is the tree in depth-first pre-order: each node, then the packets of its leaf children (slot
/// order, consecutive), zero bytes up to the next 64-byte boundary, then the subtrees of its
/// interior children (slot order). The root is at offset 0. Child slot i:
/// - interior: `child[i]` is the child node's offset in kBvhArenaUnit units (bit 31 clear);
///   `packets[i]` is how many 64-byte lines the child's own leaf packets span after it (at most
///   255): a prefetch hint, fixed by the layout;
/// - leaf: `child[i]` is kBvhLeafFlag | the offset of its first packet, `packets[i]` its packet
///   count (1..255);
/// - empty: `child[i]` is kBvhLeafFlag, `packets[i]` is 0, the box is inverted (+inf / -inf).
/// `bounds[axis][0][i]` and `bounds[axis][1][i]` are child i's min and max on that axis.
template <int W>
struct BvhWideNode {
  float bounds[3][2][W];
  std::uint32_t child[W];
  std::uint8_t packets[W];
  std::uint8_t reserved[W == 4 ? 12 : W == 8 ? 24 : 48];  // zero; pads to whole cache lines
};
using BvhNode4 = BvhWideNode<4>;
using BvhNode8 = BvhWideNode<8>;
using BvhNode16 = BvhWideNode<16>;  // float boxes only (no BvhQuantizedNode<16>)
static_assert(sizeof(BvhNode4) == 128);
static_assert(sizeof(BvhNode8) == 256);
static_assert(sizeof(BvhNode16) == 512);
static_assert(offsetof(BvhNode4, child) == 96 && offsetof(BvhNode4, packets) == 112);
static_assert(offsetof(BvhNode8, child) == 192 && offsetof(BvhNode8, packets) == 224);
static_assert(offsetof(BvhNode16, child) == 384 && offsetof(BvhNode16, packets) == 448);

/// A wide node with quantised child boxes (Ylitie et al. 2017, here per axis): the same children
/// as BvhWideNode, each box plane one byte relative to the node. Child i's box on axis a is
/// [origin[a] + float(q[a][0][i]) * 2^exponent[a], origin[a] + float(q[a][1][i]) * 2^exponent[a]],
/// computed in float exactly so (the product is exact, the sum rounds once): the builder picks
/// the bytes so that this box contains the child's float box. Empty slot: q 255 / 0 (inverted).
template <int W>
struct BvhQuantizedNode {
  float origin[3];
  std::int8_t exponent[3];  // scale 2^exponent, in [-126, 127]
  std::uint8_t reserved0;
  std::uint8_t q[3][2][W];
  std::uint32_t child[W];
  std::uint8_t packets[W];
  std::uint8_t reserved[W == 4 ? 4 : 24];  // zero; pads the node to whole cache lines
};
using BvhQNode4 = BvhQuantizedNode<4>;
using BvhQNode8 = BvhQuantizedNode<8>;
static_assert(sizeof(BvhQNode4) == 64);
static_assert(sizeof(BvhQNode8) == 128);
static_assert(offsetof(BvhQNode4, q) == 16 && offsetof(BvhQNode4, child) == 40);
static_assert(offsetof(BvhQNode8, q) == 16 && offsetof(BvhQNode8, child) == 64);
static_assert(offsetof(BvhQNode4, packets) == 56 && offsetof(BvhQNode8, packets) == 96);

/// The scale 2^e of a quantised node's axis, as float bits (e in [-126, 127]; other values of
/// a forged node still give some float, never an out-of-range read).
inline float bvh_quantized_scale(std::int8_t e) {
  const std::uint32_t bits = std::uint32_t(std::int32_t(e) + 127) << 23;
  float f;
  __builtin_memcpy(&f, &bits, sizeof f);
  return f;
}

/// Child k's box as traversal sees it, from either node type.
template <int W>
void bvh_child_box(const BvhWideNode<W>& n, int k, float lo[3], float hi[3]) {
  for (int a = 0; a < 3; ++a) lo[a] = n.bounds[a][0][k], hi[a] = n.bounds[a][1][k];
}
template <int W>
void bvh_child_box(const BvhQuantizedNode<W>& n, int k, float lo[3], float hi[3]) {
  for (int a = 0; a < 3; ++a) {
    const float scale = bvh_quantized_scale(n.exponent[a]);
    lo[a] = n.origin[a] + float(n.q[a][0][k]) * scale;
    hi[a] = n.origin[a] + float(n.q[a][1][k]) * scale;
  }
}

/// Four triangles, structure-of-arrays: `v[corner][axis][lane]`, the corners exactly as the
/// watertight test (Woop et al. 2013) consumes them, and each lane's primitive id. A leaf's last
/// packet repeats its last triangle in the unused lanes (same primitive id), so every lane is a
/// real triangle.
struct BvhTrianglePacket {
  float v[3][3][kBvhPacketSize];
  std::uint32_t prim[kBvhPacketSize];
};
static_assert(sizeof(BvhTrianglePacket) == 160 && sizeof(BvhTrianglePacket) % kBvhArenaUnit == 0);

/// Packets per leaf at most (the count is a byte).
inline constexpr std::uint32_t kBvhMaxLeafPackets = 255;

}  // namespace kiln::format
