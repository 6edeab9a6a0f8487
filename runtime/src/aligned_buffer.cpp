#include "kiln/runtime/aligned_buffer.hpp"

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <new>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace kiln {

constexpr std::size_t kHugePage = std::size_t{2} << 20;

void advise_huge_pages([[maybe_unused]] const void* p, [[maybe_unused]] std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  const auto at = reinterpret_cast<std::uintptr_t>(p);
  const std::uintptr_t begin = (at + kHugePage - 1) & ~(kHugePage - 1);
  const std::uintptr_t end = (at + bytes) & ~(kHugePage - 1);
  if (end > begin) ::madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
#endif
}

AlignedBuffer::AlignedBuffer(std::size_t size, std::size_t alignment) : size_(size) {
  // A multiple of the alignment asked for, and non-zero (zeroed, as before, up to there).
  const std::size_t padded = size == 0 ? alignment : (size + alignment - 1) / alignment * alignment;
  // posix_memalign wants a multiple of the pointer size, and takes any size. Buffers of a huge
  // page or more start on a 2 MiB boundary so that all their whole 2 MiB pages can be huge.
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
