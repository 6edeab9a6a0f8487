#include "kiln/runtime/aligned_buffer.hpp"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <new>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace kiln {

namespace {

constexpr std::size_t kHugePage = std::size_t{2} << 20;
constexpr std::size_t kPage = 4096;

// Buffers of a huge page or more start on a 2 MiB boundary and ask for transparent huge pages
// (as Embree's allocator does): a tree walked by incoherent rays touches pages at random, and
// with 4 KiB pages a tree beyond the TLB's reach (a few MiB) pays a page walk on most node
// visits. Only a hint: where the kernel has no huge pages to give (or THP is off), 4 KiB pages
// as before. The tail beyond the last 2 MiB stays on small pages; nothing is padded for it.
void advise_huge_pages([[maybe_unused]] void* p, [[maybe_unused]] std::size_t size) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  if (size >= kHugePage) ::madvise(p, (size + kPage - 1) / kPage * kPage, MADV_HUGEPAGE);
#endif
}

}  // namespace

AlignedBuffer::AlignedBuffer(std::size_t size, std::size_t alignment) : size_(size) {
  // A multiple of the alignment asked for, and non-zero (zeroed, as before, up to there).
  const std::size_t padded = size == 0 ? alignment : (size + alignment - 1) / alignment * alignment;
  // posix_memalign wants a multiple of the pointer size, and takes any size.
  std::size_t boundary = std::max(alignment, sizeof(void*));
  if (padded >= kHugePage) boundary = std::max(boundary, kHugePage);
  void* p = nullptr;
  if (::posix_memalign(&p, boundary, padded) != 0) throw std::bad_alloc();
  advise_huge_pages(p, padded);
  std::memset(p, 0, padded);
  bytes_.reset(static_cast<std::byte*>(p));
}

void AlignedBuffer::Free::operator()(std::byte* p) const {
  std::free(p);
}

}  // namespace kiln
