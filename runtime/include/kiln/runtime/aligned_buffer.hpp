#pragma once

#include <cstddef>
#include <memory>
#include <span>

namespace kiln {

// Owned, zero-initialised bytes on a given alignment: where compressed sections are inflated so
// they can be viewed as typed spans exactly like mapped ones.
class AlignedBuffer {
 public:
  AlignedBuffer() = default;
  AlignedBuffer(std::size_t size, std::size_t alignment);

  std::byte* data() { return bytes_.get(); }
  const std::byte* data() const { return bytes_.get(); }
  std::size_t size() const { return size_; }
  std::span<const std::byte> bytes() const { return {bytes_.get(), size_}; }

 private:
  struct Free {
    void operator()(std::byte* p) const;
  };
  std::unique_ptr<std::byte, Free> bytes_;
  std::size_t size_ = 0;
};

/// Asks Linux to back the whole 2 MiB pages inside [p, p + bytes) with transparent huge pages
/// when they are first touched (madvise MADV_HUGEPAGE; elsewhere a no-op), as Embree's allocator
/// does for its trees and build arrays: a large array then takes a page fault per 2 MiB, not per
/// 4 KiB, and rays walking a tree at random miss the TLB less. Only a hint: the bytes never
/// change, and nothing happens where the kernel declines.
void advise_huge_pages(const void* p, std::size_t bytes);

}  // namespace kiln
