#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace kiln {

// XXH3-64 with seed 0: the checksum of headers, section tables, sections and source files.
std::uint64_t xxh3_64(std::span<const std::byte> bytes);

}  // namespace kiln
