// The wide BVH view's structural check, its view of a blob's structure, and the choice of
// traversal kernel (run-time CPU dispatch; KILN_BVH_KERNEL forces one).
#include <algorithm>
#include <cstdlib>
#include <cstring>
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

BvhKernel bvh_auto_kernel(std::uint32_t width) {
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
  // AVX-512 measured no faster than AVX2 on 8-wide nodes (docs/BENCHMARKS.md): AVX2 first; a
  // 16-wide node fills one 512-bit register per plane, two 256-bit ones: AVX-512 first.
  const BvhKernel wide = width == 16 ? BvhKernel::kAvx512 : BvhKernel::kAvx2;
  const BvhKernel other = width == 16 ? BvhKernel::kAvx2 : BvhKernel::kAvx512;
  for (const BvhKernel k : {wide, other, BvhKernel::kSse})
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

// The depth-first walk that fixes where everything lies: each node where the cursor stands (a
// line boundary), its leaves' packets right after it in slot order, padding to the next line,
// then its interior children's subtrees in slot order; nothing deeper than the kernels' stacks
// allow, and nothing left over. Counts the nodes and packets.
template <class Node>
void check_arena(std::span<const std::byte> arena, std::size_t& node_count,
                 std::size_t& packet_count, const std::string& name) {
  constexpr int W = int(sizeof(Node::child) / sizeof(Node::child[0]));
  auto fail = [&](const std::string& what) { throw BlobError(name + ": " + what); };
  struct Pending {
    std::uint32_t word, hint, depth;
  };
  std::vector<Pending> stack{{0, 0, 1}};
  std::size_t at = 0;  // the cursor, in bytes
  const std::size_t size = arena.size();
  while (!stack.empty()) {
    const Pending p = stack.back();
    stack.pop_back();
    if (std::size_t(p.word) * format::kBvhArenaUnit != at)
      fail("node at unit " + std::to_string(p.word) + " is not where depth-first order puts it");
    if (sizeof(Node) > size - at) fail("a node runs past the end of the arena");
    if (p.depth > format::kBvhMaxDepth) fail("deeper than " + std::to_string(format::kBvhMaxDepth));
    Node n;
    std::memcpy(&n, arena.data() + at, sizeof n);
    at += sizeof n;
    node_count += 1;
    const std::size_t leaves = at;
    for (int k = 0; k < W; ++k) {
      if (!(n.child[k] & format::kBvhLeafFlag)) continue;
      const std::uint32_t first = n.child[k] & ~format::kBvhLeafFlag, packets = n.packets[k];
      if (packets == 0 && first == 0) continue;  // an empty slot
      if (packets == 0 || std::size_t(first) * format::kBvhArenaUnit != at ||
          packets * sizeof(format::BvhTrianglePacket) > size - at)
        fail("a leaf's packets at unit " + std::to_string(first) + " (" + std::to_string(packets) +
             ") are out of order or out of range");
      at += packets * sizeof(format::BvhTrianglePacket);
      packet_count += packets;
    }
    const std::size_t lines = (at - leaves + format::kBvhArenaLine - 1) / format::kBvhArenaLine;
    if (p.depth > 1 && p.hint != std::min<std::size_t>(lines, 255))
      fail("node at unit " + std::to_string(p.word) + " has a wrong prefetch hint");
    at = leaves + lines * format::kBvhArenaLine;
    if (at > size) fail("the arena ends inside a node's padding");
    for (int k = W - 1; k >= 0; --k)
      if (!(n.child[k] & format::kBvhLeafFlag))
        stack.push_back({n.child[k], n.packets[k], p.depth + 1});
  }
  if (at != size) fail(std::to_string(size - at) + " bytes after the last node");
}

}  // namespace

BvhWideView::BvhWideView(std::uint32_t width, bool quantized, std::span<const std::byte> arena,
                         const std::string& name, BvhKernel kernel)
    : width_(width), quantized_(quantized), arena_(arena) {
  auto fail = [&](const std::string& what) { throw BlobError(name + ": " + what); };
  if (width != 4 && width != 8 && width != 16)
    fail("width " + std::to_string(width) + " is not 4, 8 or 16");
  if (width == 16 && quantized) fail("16-wide nodes have float boxes only");
  if (arena.empty()) fail("no nodes");
  if (width == 16)
    check_arena<format::BvhNode16>(arena, node_count_, packet_count_, name);
  else if (quantized)
    width == 4 ? check_arena<format::BvhQNode4>(arena, node_count_, packet_count_, name)
               : check_arena<format::BvhQNode8>(arena, node_count_, packet_count_, name);
  else
    width == 4 ? check_arena<format::BvhNode4>(arena, node_count_, packet_count_, name)
               : check_arena<format::BvhNode8>(arena, node_count_, packet_count_, name);
  kernel_id_ = kernel == BvhKernel::kAuto ? bvh_auto_kernel(width) : kernel;
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
  if (d->width() != 4 && d->width() != 8 && d->width() != 16)
    blob.fail("structure '" + name + "' is a " + std::to_string(d->width()) + "-wide BVH");
  // Blob::open checked the arena section's kind and size (and refused the layout before it).
  const BvhWideView view(d->width(), d->quantized(), blob.section_bytes(d->wide_arena()),
                         blob.name() + ": " + name, kernel);
  if (view.node_count() != d->wide_node_count() || view.packet_count() != d->packet_count())
    blob.fail("structure '" + name + "' holds " + std::to_string(view.node_count()) +
              " nodes and " + std::to_string(view.packet_count()) + " packets, its description " +
              std::to_string(d->wide_node_count()) + " and " + std::to_string(d->packet_count()));
  return view;
}

}  // namespace kiln
