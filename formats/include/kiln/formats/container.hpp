// Container v2: the fixed-width, little-endian header and section table at the start of every
// .kiln blob. Shared by the writer and the reader; see docs/FORMAT.md for every byte.
#pragma once

#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>

namespace kiln::format {

static_assert(std::endian::native == std::endian::little,
              "Kiln blobs are little-endian and mapped in place; big-endian hosts are unsupported");

// PNG/KTX-style identifier: the high bytes catch 7-bit transfers, CR LF / LF catch
// text-mode line-ending conversion, 0x1A stops DOS `type`.
inline constexpr std::array<std::uint8_t, 12> kIdentifier = {0xAB, 'K',  'I',  'L',  'N',  ' ',
                                                             '1',  0xBB, '\r', '\n', 0x1A, '\n'};

inline constexpr std::uint16_t kVersionMajor = 2;
inline constexpr std::uint16_t kVersionMinor = 0;

struct FileHeader {
  std::uint8_t identifier[12];
  std::uint16_t version_major;
  std::uint16_t version_minor;
  std::uint32_t header_size;  // sizeof(FileHeader)
  std::uint32_t flags;        // no flags are defined in v2.0; must be zero
  std::uint64_t file_size;    // the whole blob, in bytes
  std::uint64_t section_table_offset;
  std::uint32_t section_count;
  std::uint32_t section_entry_size;      // sizeof(SectionEntry)
  std::uint64_t section_table_checksum;  // XXH3-64 of the section table bytes
  std::uint64_t header_checksum;         // XXH3-64 of bytes [0, 56) of this header
};
static_assert(sizeof(FileHeader) == 64);
static_assert(offsetof(FileHeader, version_major) == 12);
static_assert(offsetof(FileHeader, version_minor) == 14);
static_assert(offsetof(FileHeader, header_size) == 16);
static_assert(offsetof(FileHeader, flags) == 20);
static_assert(offsetof(FileHeader, file_size) == 24);
static_assert(offsetof(FileHeader, section_table_offset) == 32);
static_assert(offsetof(FileHeader, section_count) == 40);
static_assert(offsetof(FileHeader, section_entry_size) == 44);
static_assert(offsetof(FileHeader, section_table_checksum) == 48);
static_assert(offsetof(FileHeader, header_checksum) == 56);
inline constexpr std::size_t kHeaderChecksummedBytes = offsetof(FileHeader, header_checksum);

constexpr std::uint32_t fourcc(char a, char b, char c, char d) {
  return std::uint32_t(std::uint8_t(a)) | std::uint32_t(std::uint8_t(b)) << 8 |
         std::uint32_t(std::uint8_t(c)) << 16 | std::uint32_t(std::uint8_t(d)) << 24;
}

enum class SectionFlag : std::uint16_t {
  kRequired = 1u << 0,  // a reader that does not know the kind must refuse the blob
};
inline constexpr std::uint16_t kKnownSectionFlags = std::uint16_t(SectionFlag::kRequired);

enum class Codec : std::uint8_t {
  kNone = 0,
  kZstd = 1,  // one zstd frame holding the whole section
};

struct SectionEntry {
  std::uint32_t kind;  // FourCC, see section_kinds.hpp
  std::uint16_t flags;
  std::uint8_t codec;
  std::uint8_t alignment_log2;  // the section's offset is a multiple of 1 << alignment_log2
  std::uint64_t offset;         // from the start of the file
  std::uint64_t stored_size;    // bytes in the file
  std::uint64_t raw_size;       // bytes after decoding (== stored_size when codec is none)
  std::uint64_t element_count;
  std::uint32_t element_size;  // element_count * element_size == raw_size
  std::uint32_t reserved0;     // zero
  std::uint64_t checksum;      // XXH3-64 of the stored bytes
  std::uint64_t reserved1;     // zero
};
static_assert(sizeof(SectionEntry) == 64);
static_assert(offsetof(SectionEntry, kind) == 0);
static_assert(offsetof(SectionEntry, flags) == 4);
static_assert(offsetof(SectionEntry, codec) == 6);
static_assert(offsetof(SectionEntry, alignment_log2) == 7);
static_assert(offsetof(SectionEntry, offset) == 8);
static_assert(offsetof(SectionEntry, stored_size) == 16);
static_assert(offsetof(SectionEntry, raw_size) == 24);
static_assert(offsetof(SectionEntry, element_count) == 32);
static_assert(offsetof(SectionEntry, element_size) == 40);
static_assert(offsetof(SectionEntry, reserved0) == 44);
static_assert(offsetof(SectionEntry, checksum) == 48);
static_assert(offsetof(SectionEntry, reserved1) == 56);

// Sections are aligned so the runtime can hand out typed spans straight from the mapping;
// large ones start on a page so they map (and page in) independently.
inline constexpr std::uint32_t kSmallSectionAlignmentLog2 = 6;   // 64 bytes
inline constexpr std::uint32_t kLargeSectionAlignmentLog2 = 12;  // 4096 bytes
inline constexpr std::uint64_t kLargeSectionThreshold = 1u << 20;
inline constexpr std::uint32_t kMinSectionAlignmentLog2 = 3;
inline constexpr std::uint32_t kMaxSectionAlignmentLog2 = 16;

constexpr std::uint32_t section_alignment_log2(std::uint64_t stored_size) {
  return stored_size >= kLargeSectionThreshold ? kLargeSectionAlignmentLog2
                                               : kSmallSectionAlignmentLog2;
}

}  // namespace kiln::format
