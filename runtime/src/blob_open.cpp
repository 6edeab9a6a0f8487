// Opening a blob: every check here is O(sections) so a million-triangle blob opens in
// microseconds; checksums and per-element checks live in Blob::verify.
#include <zstd.h>

#include <algorithm>
#include <cstring>
#include <limits>

#include "kiln/formats/section_kinds.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/checksum.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/structure_registry.hpp"

namespace kiln {

namespace {

using format::FileHeader;
using format::SectionEntry;

// Limits given to the FlatBuffers verifier: far above anything the writer produces, low enough
// that a hostile manifest cannot make verification slow.
constexpr flatbuffers::uoffset_t kManifestMaxDepth = 64;
constexpr flatbuffers::uoffset_t kManifestMaxTables = 1u << 22;
constexpr std::uint64_t kManifestMaxSize = 1u << 30;

// The manifest's and the inputs' section kinds, and every registered structure kind's.
}  // namespace
bool is_event_section_kind(std::uint32_t kind);  // blob_events.cpp (issue 18)
namespace {

bool is_known_kind(std::uint32_t kind) {
  if (kind == format::kSectionManifest ||
      std::find(std::begin(format::kInputSectionKinds), std::end(format::kInputSectionKinds),
                kind) != std::end(format::kInputSectionKinds))
    return true;
  if (is_event_section_kind(kind)) return true;  // issue 18: blob_events.cpp
  for (const StructureKind* structure : structure_kinds())
    if (std::find(structure->sections.begin(), structure->sections.end(), kind) !=
        structure->sections.end())
      return true;
  return false;
}

}  // namespace

Blob Blob::open_file(const std::string& path) {
  Blob blob;
  blob.name_ = path;
  blob.file_ = MappedFile(path);
  blob.bytes_ = blob.file_.bytes();
  blob.validate();
  return blob;
}

Blob Blob::open_memory(std::span<const std::byte> bytes, std::string name) {
  Blob blob;
  blob.name_ = std::move(name);
  blob.bytes_ = bytes;
  if (reinterpret_cast<std::uintptr_t>(bytes.data()) % 16 != 0)
    blob.fail("buffer is not 16-byte aligned");
  blob.validate();
  return blob;
}

std::optional<Blob> Blob::try_open_file(const std::string& path, std::string& error) {
  try {
    return open_file(path);
  } catch (const BlobError& e) {
    error = e.what();
  } catch (const std::bad_alloc&) {
    error = path + ": out of memory while opening";
  }
  return std::nullopt;
}

void Blob::fail(const std::string& what) const {
  throw BlobError(name_ + ": " + what);
}

void Blob::fail_section(std::uint32_t index, const std::string& what) const {
  std::string kind = "?";
  if (index < sections_.size()) kind = format::fourcc_to_string(sections_[index].kind);
  throw BlobError(name_ + ": section " + std::to_string(index) + " (" + kind + "): " + what);
}

void Blob::validate() {
  validate_header();
  validate_section_table();
  decode_sections();
  validate_manifest();
  validate_input();
  validate_structures();
}

void Blob::validate_header() {
  if (bytes_.size() < sizeof(FileHeader))
    fail("too small to be a kiln blob (" + std::to_string(bytes_.size()) + " bytes)");
  std::memcpy(&header_, bytes_.data(), sizeof(FileHeader));
  const auto& id = format::kIdentifier;
  if (std::memcmp(header_.identifier, id.data(), id.size()) != 0) {
    // The first eight bytes survive a text-mode transfer; the line-ending bytes do not.
    if (std::memcmp(header_.identifier, id.data(), 8) == 0)
      fail(
          "identifier damaged after byte 8: the file went through a text-mode (line-ending) "
          "conversion");
    fail("not a kiln blob (wrong identifier)");
  }
  const std::string version =
      std::to_string(header_.version_major) + "." + std::to_string(header_.version_minor);
  if (header_.version_major < format::kVersionMajor)
    fail("format " + version + " blob: this kiln reads format " +
         std::to_string(format::kVersionMajor) +
         ".x; rebuild it with kiln build and the same inputs");
  if (header_.version_major != format::kVersionMajor)
    fail("unsupported major version " + std::to_string(header_.version_major) +
         " (this reader reads " + std::to_string(format::kVersionMajor) + ".x)");
  if (header_.version_minor > format::kVersionMinor)
    fail("version " + version + " is newer than this reader (" +
         std::to_string(format::kVersionMajor) + "." + std::to_string(format::kVersionMinor) + ")");
  if (header_.header_size != sizeof(FileHeader))
    fail("header size " + std::to_string(header_.header_size) + " is not 64");
  const auto header_sum = xxh3_64(bytes_.first(format::kHeaderChecksummedBytes));
  if (header_sum != header_.header_checksum) fail("header checksum mismatch (header is corrupt)");
  if (header_.flags != 0) fail("unknown header flags " + std::to_string(header_.flags));
  if (header_.file_size != bytes_.size())
    fail("file is " + std::to_string(bytes_.size()) + " bytes but the header says " +
         std::to_string(header_.file_size) + " (truncated or padded)");
}

void Blob::validate_section_table() {
  if (header_.section_entry_size != sizeof(SectionEntry))
    fail("section entry size " + std::to_string(header_.section_entry_size) + " is not 64");
  const std::uint64_t file_size = bytes_.size();
  const std::uint64_t table_offset = header_.section_table_offset;
  if (table_offset < sizeof(FileHeader) || table_offset % 8 != 0 || table_offset > file_size)
    fail("section table offset " + std::to_string(table_offset) + " is out of range");
  const std::uint64_t max_count = (file_size - table_offset) / sizeof(SectionEntry);
  if (header_.section_count == 0) fail("no sections (a blob needs at least the manifest)");
  if (header_.section_count > max_count)
    fail("section count " + std::to_string(header_.section_count) +
         " does not fit in the file (at most " + std::to_string(max_count) + ")");
  const auto table = bytes_.subspan(table_offset, header_.section_count * sizeof(SectionEntry));
  if (xxh3_64(table) != header_.section_table_checksum)
    fail("section table checksum mismatch (table is corrupt)");
  sections_.resize(header_.section_count);
  std::memcpy(sections_.data(), table.data(), table.size());

  const std::uint64_t table_end = table_offset + table.size();
  std::uint64_t previous_end = table_end;
  for (std::uint32_t i = 0; i < sections_.size(); ++i) {
    const SectionEntry& s = sections_[i];
    if ((s.flags & ~format::kKnownSectionFlags) != 0) fail_section(i, "unknown section flags");
    if (s.reserved0 != 0 || s.reserved1 != 0) fail_section(i, "reserved fields are not zero");
    if (s.codec != std::uint8_t(format::Codec::kNone) &&
        s.codec != std::uint8_t(format::Codec::kZstd))
      fail_section(i, "unknown codec " + std::to_string(s.codec));
    if (s.alignment_log2 < format::kMinSectionAlignmentLog2 ||
        s.alignment_log2 > format::kMaxSectionAlignmentLog2)
      fail_section(i, "alignment 2^" + std::to_string(s.alignment_log2) + " is out of range");
    if (s.offset % (std::uint64_t{1} << s.alignment_log2) != 0)
      fail_section(i, "offset " + std::to_string(s.offset) + " is not aligned to " +
                          std::to_string(std::uint64_t{1} << s.alignment_log2));
    // Sorted, non-overlapping, after the table: checked as one ordering so overlap and
    // table collisions cannot slip between separate checks.
    if (s.offset < previous_end)
      fail_section(i, "offset " + std::to_string(s.offset) +
                          " overlaps the previous section or the section table");
    if (s.offset > file_size || s.stored_size > file_size - s.offset)
      fail_section(i, "offset " + std::to_string(s.offset) + " + size " +
                          std::to_string(s.stored_size) + " runs past the end of the file (" +
                          std::to_string(file_size) + " bytes)");
    previous_end = s.offset + s.stored_size;
    if (s.element_size == 0) fail_section(i, "element size is zero");
    if (s.element_count > std::numeric_limits<std::uint64_t>::max() / s.element_size ||
        s.element_count * s.element_size != s.raw_size)
      fail_section(i, "element count " + std::to_string(s.element_count) + " x size " +
                          std::to_string(s.element_size) + " does not equal the raw size " +
                          std::to_string(s.raw_size));
    if (s.codec == std::uint8_t(format::Codec::kNone) && s.stored_size != s.raw_size)
      fail_section(i, "uncompressed section has stored size != raw size");
    if (!is_known_kind(s.kind) && (s.flags & std::uint16_t(format::SectionFlag::kRequired)))
      fail_section(i, "unknown section kind marked REQUIRED (written by a newer tool)");
  }
  if (previous_end != file_size)
    fail("file has " + std::to_string(file_size - previous_end) + " bytes after the last section");
}

void Blob::decode_sections() {
  decoded_.resize(sections_.size());
  for (std::uint32_t i = 0; i < sections_.size(); ++i) {
    const SectionEntry& s = sections_[i];
    if (s.codec != std::uint8_t(format::Codec::kZstd) || !is_known_kind(s.kind)) continue;
    const auto stored = bytes_.subspan(s.offset, s.stored_size);
    const auto frame_size = ZSTD_getFrameContentSize(stored.data(), stored.size());
    if (frame_size == ZSTD_CONTENTSIZE_ERROR || frame_size == ZSTD_CONTENTSIZE_UNKNOWN)
      fail_section(i, "not a zstd frame with a known content size");
    if (frame_size != s.raw_size)
      fail_section(i, "zstd frame holds " + std::to_string(frame_size) + " bytes, expected " +
                          std::to_string(s.raw_size));
    if (ZSTD_findFrameCompressedSize(stored.data(), stored.size()) != stored.size())
      fail_section(i, "zstd frame does not span the stored bytes");
    AlignedBuffer buffer(s.raw_size, std::size_t{1} << s.alignment_log2);
    const std::size_t got =
        ZSTD_decompress(buffer.data(), buffer.size(), stored.data(), stored.size());
    if (ZSTD_isError(got)) fail_section(i, std::string("zstd: ") + ZSTD_getErrorName(got));
    if (got != s.raw_size) fail_section(i, "zstd inflated to the wrong size");
    decoded_[i] = std::move(buffer);
  }
}

std::span<const std::byte> Blob::section_bytes(std::uint32_t index) const {
  const SectionEntry& s = sections_.at(index);
  if (s.codec == std::uint8_t(format::Codec::kZstd)) return decoded_[index].bytes();
  return bytes_.subspan(s.offset, s.stored_size);
}

void Blob::validate_manifest() {
  const SectionEntry& s = sections_[0];
  if (s.kind != format::kSectionManifest) fail_section(0, "section 0 is not the manifest");
  if (s.codec != std::uint8_t(format::Codec::kNone))
    fail_section(0, "manifest must not be compressed");
  if (s.element_size != 1) fail_section(0, "manifest element size must be 1");
  if (s.raw_size > kManifestMaxSize || s.raw_size < 8)
    fail_section(0, "manifest size out of range");
  const auto bytes = section_bytes(0);
  const auto* data = reinterpret_cast<const std::uint8_t*>(bytes.data());
  if (!flatbuffers::BufferHasIdentifier(data, schema::ManifestIdentifier()))
    fail_section(0, "manifest has the wrong FlatBuffers identifier");
  flatbuffers::Verifier verifier(data, bytes.size(), kManifestMaxDepth, kManifestMaxTables);
  if (!schema::VerifyManifestBuffer(verifier))
    fail_section(0, "manifest FlatBuffer fails verification");
  manifest_ = schema::GetManifest(data);
  for (std::uint32_t i = 1; i < sections_.size(); ++i)
    if (sections_[i].kind == format::kSectionManifest) fail_section(i, "a second manifest");
}

}  // namespace kiln
