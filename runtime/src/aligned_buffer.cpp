#include "kiln/runtime/aligned_buffer.hpp"

#include <cstdlib>
#include <cstring>
#include <new>

namespace kiln {

AlignedBuffer::AlignedBuffer(std::size_t size, std::size_t alignment) : size_(size) {
  // aligned_alloc wants a size that is a multiple of the alignment, and non-zero.
  const std::size_t padded = (size + alignment - 1) / alignment * alignment;
  void* p = std::aligned_alloc(alignment, padded == 0 ? alignment : padded);
  if (p == nullptr) throw std::bad_alloc();
  std::memset(p, 0, padded == 0 ? alignment : padded);
  bytes_.reset(static_cast<std::byte*>(p));
}

void AlignedBuffer::Free::operator()(std::byte* p) const {
  std::free(p);
}

}  // namespace kiln
