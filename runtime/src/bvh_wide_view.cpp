// The wide BVH view's structural check, its view of a blob's structure, and the choice of
// traversal kernel (run-time CPU dispatch; KILN_BVH_KERNEL forces one).
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "bvh_wide_kernels.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/bvh_wide.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/manifest.hpp"

namespace kiln {

const char* bvh_kernel_name(BvhKernel kernel) {
  switch (kernel) {
    case BvhKernel::kAuto:
      return "auto";
    case BvhKernel::kScalar:
      return "scalar";
    case BvhKernel::kSse:
      return "sse";
    case BvhKernel::kAvx2:
      return "avx2";
    case BvhKernel::kAvx512:
      return "avx512";
  }
  return "?";
}

bool bvh_kernel_supported(BvhKernel kernel) {
#if defined(__x86_64__) || defined(__i386__)
  switch (kernel) {
    case BvhKernel::kAvx512:
      return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
             bvh_wide::avx512_kernel(8, false) != nullptr;
    case BvhKernel::kAvx2:
      return __builtin_cpu_supports("avx2") && bvh_wide::avx2_kernel(8, false);
    case BvhKernel::kSse:
      return bvh_wide::sse_kernel(8, false) != nullptr;
    default:
      return true;
  }
#else
  return kernel == BvhKernel::kAuto || kernel == BvhKernel::kScalar;
#endif
}

BvhKernel bvh_auto_kernel() {
  if (const char* forced = std::getenv("KILN_BVH_KERNEL"); forced != nullptr && *forced) {
    for (const BvhKernel k :
         {BvhKernel::kScalar, BvhKernel::kSse, BvhKernel::kAvx2, BvhKernel::kAvx512})
      if (std::string_view(forced) == bvh_kernel_name(k)) {
        if (!bvh_kernel_supported(k))
          throw std::invalid_argument(std::string("KILN_BVH_KERNEL=") + forced +
                                      ": this CPU cannot run that kernel");
        return k;
      }
    throw std::invalid_argument(std::string("KILN_BVH_KERNEL=") + forced +
                                ": not scalar, sse, avx2 or avx512");
  }
  // AVX-512 measured no faster than AVX2 on 8-wide nodes (docs/BENCHMARKS.md): AVX2 first.
  for (const BvhKernel k : {BvhKernel::kAvx2, BvhKernel::kAvx512, BvhKernel::kSse})
    if (bvh_kernel_supported(k)) return k;
  return BvhKernel::kScalar;
}

namespace {

const BvhWideKernel* kernel_table(BvhKernel kernel, std::uint32_t width, bool quantized) {
  switch (kernel) {
    case BvhKernel::kSse:
      return bvh_wide::sse_kernel(width, quantized);
    case BvhKernel::kAvx2:
      return bvh_wide::avx2_kernel(width, quantized);
    case BvhKernel::kAvx512:
      return bvh_wide::avx512_kernel(width, quantized);
    default:
      return bvh_wide::scalar_kernel(width, quantized);
  }
}

std::size_t node_size(std::uint32_t width, bool quantized) {
  if (quantized) return width == 4 ? sizeof(format::BvhQNode4) : sizeof(format::BvhQNode8);
  return width == 4 ? sizeof(format::BvhNode4) : sizeof(format::BvhNode8);
}

// Pre-order walk: the n-th node reached must be node n (no sharing, cycles or unreachable
// nodes), leaves take the packets in order, nothing deeper than the kernels' stacks allow.
template <int W, class Node>
void check_nodes(std::span<const Node> nodes, std::size_t packet_count, const std::string& name) {
  auto fail = [&](const std::string& what) { throw BlobError(name + ": " + what); };
  struct Pending {
    std::uint32_t word, packets, depth;
  };
  std::vector<Pending> stack{{0, 0, 1}};
  std::uint64_t next_node = 0, next_packet = 0;
  while (!stack.empty()) {
    const Pending p = stack.back();
    stack.pop_back();
    if (p.word & format::kBvhLeafFlag) {
      const std::uint32_t first = p.word & ~format::kBvhLeafFlag;
      if (p.packets == 0 && first == 0) continue;  // an empty slot
      if (p.packets == 0 || first != next_packet || p.packets > packet_count - next_packet)
        fail("a leaf's packets [" + std::to_string(first) + ", +" + std::to_string(p.packets) +
             ") are out of order or out of range");
      next_packet += p.packets;
      continue;
    }
    if (p.word != next_node || p.word >= nodes.size())
      fail("node " + std::to_string(p.word) + " is not where depth-first order puts it");
    if (p.depth > format::kBvhMaxDepth) fail("deeper than " + std::to_string(format::kBvhMaxDepth));
    next_node += 1;
    const auto& n = nodes[p.word];
    for (int k = W - 1; k >= 0; --k) {
      const bool leaf = (n.child[k] & format::kBvhLeafFlag) != 0;
      if (!leaf && n.packets[k] != 0)
        fail("node " + std::to_string(p.word) + " has packets on an interior child");
      stack.push_back({n.child[k], n.packets[k], p.depth + 1});
    }
  }
  if (next_node != nodes.size())
    fail(std::to_string(nodes.size() - next_node) + " nodes are unreachable");
  if (next_packet != packet_count)
    fail(std::to_string(packet_count - next_packet) + " packets are in no leaf");
}

}  // namespace

BvhWideView::BvhWideView(std::uint32_t width, bool quantized, std::span<const std::byte> nodes,
                         std::span<const format::BvhTrianglePacket> packets,
                         std::span<const std::uint32_t> prim_ids, const std::string& name,
                         BvhKernel kernel)
    : width_(width), quantized_(quantized), nodes_(nodes), packets_(packets), prim_ids_(prim_ids) {
  auto fail = [&](const std::string& what) { throw BlobError(name + ": " + what); };
  if (width != 4 && width != 8) fail("width " + std::to_string(width) + " is not 4 or 8");
  const std::size_t size = node_size(width, quantized);
  if (nodes.empty() || nodes.size() % size != 0) fail("no whole nodes");
  node_count_ = nodes.size() / size;
  if (node_count_ >= format::kBvhLeafFlag) fail("too many nodes");
  if (prim_ids.size() != packets.size() * format::kBvhPacketSize)
    fail(std::to_string(packets.size()) + " packets but " + std::to_string(prim_ids.size()) +
         " primitive ids");
  if (quantized)
    width == 4 ? check_nodes<4>(qnodes4(), packets.size(), name)
               : check_nodes<8>(qnodes8(), packets.size(), name);
  else
    width == 4 ? check_nodes<4>(nodes4(), packets.size(), name)
               : check_nodes<8>(nodes8(), packets.size(), name);
  kernel_id_ = kernel == BvhKernel::kAuto ? bvh_auto_kernel() : kernel;
  if (!bvh_kernel_supported(kernel_id_))
    throw std::invalid_argument(std::string("BVH kernel ") + bvh_kernel_name(kernel_id_) +
                                " is not supported on this CPU");
  kernel_ = kernel_table(kernel_id_, width, quantized);
}

BvhWideView BvhWideView::from_blob(const Blob& blob, const std::string& name, BvhKernel kernel) {
  const StructureInfo* info = blob.structure(name);
  if (info == nullptr) blob.fail("has no structure '" + name + "'");
  const auto* d = structure_table(blob, *info).desc_as<schema::BvhDesc>();
  if (d == nullptr) blob.fail("structure '" + name + "' is a " + info->kind + ", not a BVH");
  if (d->width() != 4 && d->width() != 8)
    blob.fail("structure '" + name + "' is a " + std::to_string(d->width()) + "-wide BVH");
  // Blob::open checked kinds, sizes and counts of these sections.
  return BvhWideView(d->width(), d->quantized(), blob.section_bytes(d->wide_nodes()),
                     blob.section_view<format::BvhTrianglePacket>(d->packets()),
                     blob.section_view<std::uint32_t>(d->prim_ids()), blob.name() + ": " + name,
                     kernel);
}

}  // namespace kiln
