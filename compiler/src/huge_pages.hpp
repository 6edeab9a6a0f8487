// Transparent huge pages for the builders' large arrays (Linux; elsewhere a no-op).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace kiln {

/// Asks the kernel to back the 2 MiB-aligned pages inside [p, p + bytes) with transparent huge
/// pages when they are first touched (madvise MADV_HUGEPAGE; THP in "madvise" mode, the usual
/// default, gives them to no one else). A fresh array of tens of MB otherwise takes a page fault,
/// and a page clear, per 4 KiB; Embree's allocator asks the same for its build arrays. Only a
/// hint: nothing changes if the kernel declines, and the bytes are never affected.
inline void advise_huge_pages(const void* p, std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  constexpr std::uintptr_t kHuge = std::uintptr_t(2) << 20;
  if (bytes < 2 * kHuge) return;
  const auto at = reinterpret_cast<std::uintptr_t>(p);
  const std::uintptr_t begin = (at + kHuge - 1) & ~(kHuge - 1), end = (at + bytes) & ~(kHuge - 1);
  if (end > begin) madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
#else
  (void)p, (void)bytes;
#endif
}

/// Reserves `v` for `n` elements with advise_huge_pages on the new block (before its pages are
/// touched).
template <class T, class A>
void reserve_huge(std::vector<T, A>& v, std::size_t n) {
  if (v.capacity() >= n) return;
  v.reserve(n);
  advise_huge_pages(v.data(), v.capacity() * sizeof(T));
}

/// A vector of `n` value-initialised elements on huge pages (reserve_huge, then resize).
template <class T>
std::vector<T> huge_vector(std::size_t n) {
  std::vector<T> v;
  reserve_huge(v, n);
  v.resize(n);
  return v;
}

}  // namespace kiln
