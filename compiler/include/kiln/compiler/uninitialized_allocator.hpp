// An allocator whose value-less construct leaves trivial elements uninitialised, so that a
// vector's resize does not zero memory that is written in full right after.
#pragma once

#include <memory>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

#include "kiln/runtime/aligned_buffer.hpp"  // advise_huge_pages

namespace kiln {

/// std::allocator, except that construct(p) with no arguments default-initialises (no zeroing
/// for trivial types), and that every block is advised onto transparent huge pages
/// (advise_huge_pages) before it is touched. For large arrays every byte of which the owner
/// writes before reading (in parallel, first touching its pages where it writes): build
/// references, the wide BVH arena (kiln/compiler/bvh_collapse.hpp).
template <class T>
struct UninitializedAllocator : std::allocator<T> {
  using value_type = T;
  template <class U>
  struct rebind {
    using other = UninitializedAllocator<U>;
  };
  UninitializedAllocator() noexcept = default;
  template <class U>
  UninitializedAllocator(const UninitializedAllocator<U>&) noexcept {}

  T* allocate(std::size_t n) {
    T* p = std::allocator<T>::allocate(n);
    advise_huge_pages(p, n * sizeof(T));
    return p;
  }
  template <class U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    std::construct_at(p, std::forward<Args>(args)...);
  }
};

template <class T, class U>
bool operator==(const UninitializedAllocator<T>&, const UninitializedAllocator<U>&) noexcept {
  return true;
}

/// A vector whose resize leaves new trivial elements uninitialised.
template <class T>
using UninitializedVector = std::vector<T, UninitializedAllocator<T>>;

}  // namespace kiln
