// Transparent huge pages for the builders' large arrays (Linux; elsewhere a no-op).
#pragma once

#include <cstddef>
#include <vector>

#include "kiln/compiler/uninitialized_allocator.hpp"
#include "kiln/runtime/aligned_buffer.hpp"  // advise_huge_pages

namespace kiln {

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
