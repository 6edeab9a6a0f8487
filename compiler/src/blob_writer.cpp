#include "kiln/compiler/blob_writer.hpp"

#include <zstd.h>

#include <cstring>
#include <memory>
#include <stdexcept>

#include "kiln/formats/container.hpp"
#include "kiln/runtime/checksum.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln {

namespace {

std::uint64_t align_up(std::uint64_t value, std::uint32_t alignment_log2) {
  const std::uint64_t alignment = std::uint64_t{1} << alignment_log2;
  return (value + alignment - 1) & ~(alignment - 1);
}

std::vector<std::byte> zstd_compress(std::span<const std::byte> raw, int level) {
  std::vector<std::byte> out(ZSTD_compressBound(raw.size()));
  std::unique_ptr<ZSTD_CCtx, decltype(&ZSTD_freeCCtx)> context(ZSTD_createCCtx(), ZSTD_freeCCtx);
  ZSTD_CCtx_setParameter(context.get(), ZSTD_c_compressionLevel, level);
  ZSTD_CCtx_setParameter(context.get(), ZSTD_c_checksumFlag, 0);  // the table has XXH3
  ZSTD_CCtx_setParameter(context.get(), ZSTD_c_contentSizeFlag, 1);
  const std::size_t size =
      ZSTD_compress2(context.get(), out.data(), out.size(), raw.data(), raw.size());
  if (ZSTD_isError(size)) throw std::runtime_error(std::string("zstd: ") + ZSTD_getErrorName(size));
  out.resize(size);
  return out;
}

}  // namespace

std::vector<std::byte> BlobPieces::concatenate() const {
  std::vector<std::byte> blob(size);  // zero-filled: every padding byte is zero
  for (const FilePiece& p : pieces)
    if (!p.bytes.empty()) std::memcpy(blob.data() + p.offset, p.bytes.data(), p.bytes.size());
  return blob;
}

namespace {

// The header over the finished table; its checksum covers its own first bytes.
format::FileHeader make_header(std::span<const std::byte> table_bytes, std::uint64_t file_size,
                               std::size_t count) {
  format::FileHeader header{};
  std::memcpy(header.identifier, format::kIdentifier.data(), format::kIdentifier.size());
  header.version_major = format::kVersionMajor;
  header.version_minor = format::kVersionMinor;
  header.header_size = sizeof(format::FileHeader);
  header.file_size = file_size;
  header.section_table_offset = sizeof(format::FileHeader);
  header.section_count = std::uint32_t(count);
  header.section_entry_size = sizeof(format::SectionEntry);
  header.section_table_checksum = xxh3_64(table_bytes);
  std::byte bytes[sizeof header];
  std::memcpy(bytes, &header, sizeof header);
  header.header_checksum =
      xxh3_64(std::span<const std::byte>(bytes).first(format::kHeaderChecksummedBytes));
  return header;
}

}  // namespace

BlobPieces lay_out_blob(std::span<const SectionPayload> sections,
                        const CompressionOptions& compression, unsigned threads) {
  const std::size_t count = sections.size();
  BlobPieces out;
  out.compressed.resize(count);
  if (compression.enabled) {
    parallel_for(count, threads, [&](std::size_t i) {
      if (!sections[i].compressible || sections[i].bytes.empty()) return;
      auto packed = zstd_compress(sections[i].bytes, compression.level);
      if (packed.size() < sections[i].bytes.size()) out.compressed[i] = std::move(packed);
    });
  }
  auto stored = [&](std::size_t i) {
    return out.compressed[i].empty() ? sections[i].bytes
                                     : std::span<const std::byte>(out.compressed[i]);
  };
  std::vector<format::SectionEntry> table(count);
  std::uint64_t offset = sizeof(format::FileHeader) + count * sizeof(format::SectionEntry);
  for (std::size_t i = 0; i < count; ++i) {
    const SectionPayload& s = sections[i];
    format::SectionEntry& e = table[i];
    e.kind = s.kind;
    e.flags = s.flags;
    e.codec = std::uint8_t(out.compressed[i].empty() ? format::Codec::kNone : format::Codec::kZstd);
    e.stored_size = stored(i).size();
    e.alignment_log2 = std::uint8_t(format::section_alignment_log2(e.stored_size));
    e.offset = align_up(offset, e.alignment_log2);
    e.raw_size = s.bytes.size();
    e.element_count = s.element_count;
    e.element_size = s.element_size;
    if (std::uint64_t(s.element_size) * s.element_count != s.bytes.size())
      throw std::logic_error("section element count x size != byte size");
    offset = e.offset + e.stored_size;
  }
  out.size = offset;
  parallel_for(count, threads, [&](std::size_t i) { table[i].checksum = xxh3_64(stored(i)); });

  const std::size_t table_bytes = count * sizeof(format::SectionEntry);
  out.head.resize(sizeof(format::FileHeader) + table_bytes);
  std::memcpy(out.head.data() + sizeof(format::FileHeader), table.data(), table_bytes);
  const format::FileHeader header = make_header(
      std::span<const std::byte>(out.head).subspan(sizeof(format::FileHeader)), out.size, count);
  std::memcpy(out.head.data(), &header, sizeof header);
  out.pieces.push_back({0, out.head});
  for (std::size_t i = 0; i < count; ++i) out.pieces.push_back({table[i].offset, stored(i)});
  return out;
}

}  // namespace kiln
