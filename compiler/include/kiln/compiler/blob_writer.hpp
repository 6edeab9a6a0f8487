// Lays out sections after the header and table, compresses and checksums them, and produces
// the blob's bytes. Knows nothing of what the sections mean.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "kiln/formats/container.hpp"
#include "kiln/runtime/atomic_file.hpp"

namespace kiln {

struct SectionPayload {
  std::uint32_t kind = 0;
  std::uint16_t flags = 0;
  std::uint32_t element_size = 1;
  std::uint64_t element_count = 0;
  std::span<const std::byte> bytes;  // raw (uncompressed) bytes
  bool compressible = true;          // the manifest is never compressed
};

/// A required, compressible section over `values`' elements (borrowed: keep them alive).
template <class T, class Allocator>
SectionPayload raw_section(std::uint32_t kind, const std::vector<T, Allocator>& values) {
  return {kind,          std::uint16_t(format::SectionFlag::kRequired), sizeof(T),
          values.size(), std::as_bytes(std::span<const T>(values)),     true};
}

struct CompressionOptions {
  bool enabled = false;
  int level = 9;  // single-threaded zstd at a fixed level: reproducible bytes
};

/// A blob laid out but not concatenated: the header and section table, then each section's
/// stored bytes at its offset (raw bytes borrowed from the payloads, or compressed bytes owned
/// here), zeros between. Written piece by piece (write_pieces_atomically), a blob never exists
/// twice in memory.
struct BlobPieces {
  std::vector<std::byte> head;                     // the header and the section table, at offset 0
  std::vector<std::vector<std::byte>> compressed;  // owned stored bytes of compressed sections
  std::vector<FilePiece> pieces;                   // head first, then sections by offset
  std::uint64_t size = 0;
  std::vector<std::byte> concatenate() const;
};

// sections[0] must be the manifest. Sections are compressed in parallel over `threads`; the
// output does not depend on the thread count. A compressed section that would not be smaller
// is stored raw. The payloads' bytes must outlive the result.
BlobPieces lay_out_blob(std::span<const SectionPayload> sections,
                        const CompressionOptions& compression, unsigned threads);

inline std::vector<std::byte> serialize_blob(std::span<const SectionPayload> sections,
                                             const CompressionOptions& compression,
                                             unsigned threads) {
  return lay_out_blob(sections, compression, threads).concatenate();
}

}  // namespace kiln
