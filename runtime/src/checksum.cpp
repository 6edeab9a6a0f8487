#include "kiln/runtime/checksum.hpp"

#include <xxhash.h>

namespace kiln {

std::uint64_t xxh3_64(std::span<const std::byte> bytes) {
  return XXH3_64bits(bytes.data(), bytes.size());
}

}  // namespace kiln
