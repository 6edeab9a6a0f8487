// Damaged blobs: every truncation, every single-bit flip, forged headers with valid checksums.
// Open must refuse or verify must catch each one, with a message, never a crash (the suite
// also runs under ASan + UBSan).
#include <cstring>

#include "kiln/compiler/blob_writer.hpp"
#include "kiln/compiler/build.hpp"
#include "kiln/formats/container.hpp"
#include "kiln/formats/section_kinds.hpp"
#include "kiln/runtime/checksum.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

std::vector<std::byte> small_blob(bool compress = false, const char* mesh = "assimp/OBJ/box.obj") {
  BuildOptions options;
  options.inputs = {test::mesh_path(mesh)};
  options.compression.enabled = compress;
  return compile_blob(import_scene(options.inputs, 1), options);
}

format::FileHeader header_of(const std::vector<std::byte>& blob) {
  format::FileHeader h;
  std::memcpy(&h, blob.data(), sizeof(h));
  return h;
}

format::SectionEntry entry_of(const std::vector<std::byte>& blob, std::uint32_t index) {
  format::SectionEntry e;
  std::memcpy(&e, blob.data() + 64 + 64 * index, sizeof(e));
  return e;
}

// Rewrites header and/or entry and recomputes both checksums, as a forger would.
void forge(std::vector<std::byte>& blob, const format::FileHeader& header) {
  auto h = header;
  std::memcpy(blob.data(), &h, sizeof(h));
  const std::size_t table_bytes = std::size_t(header_of(blob).section_count) * 64;
  if (64 + table_bytes <= blob.size())
    h.section_table_checksum = xxh3_64(std::span<const std::byte>(blob).subspan(64, table_bytes));
  std::memcpy(blob.data(), &h, sizeof(h));
  h.header_checksum = xxh3_64(std::span<const std::byte>(blob).first(56));
  std::memcpy(blob.data(), &h, sizeof(h));
}

void forge_entry(std::vector<std::byte>& blob, std::uint32_t index,
                 const format::SectionEntry& entry) {
  std::memcpy(blob.data() + 64 + 64 * index, &entry, sizeof(entry));
  forge(blob, header_of(blob));
}

TEST(Corruption, EveryTruncationIsRefusedOnOpen) {
  KILN_REQUIRE_CORPUS();
  const auto blob = small_blob();
  ASSERT_EQ(test::open_and_verify(blob), "");
  for (std::size_t length = 0; length < blob.size(); ++length) {
    const std::string error = test::open_only(std::span<const std::byte>(blob).first(length));
    ASSERT_NE(error, "") << "truncated to " << length;
    EXPECT_EQ(error.find('\n'), std::string::npos);
  }
  const auto error = test::open_only(std::span<const std::byte>(blob).first(blob.size() - 1));
  EXPECT_NE(error.find("truncated"), std::string::npos) << error;
}

TEST(Corruption, EverySingleBitFlipIsCaught) {
  KILN_REQUIRE_CORPUS();
  auto blob = small_blob();
  const auto header = header_of(blob);
  const std::size_t table_end = 64 + std::size_t(header.section_count) * 64;
  for (std::size_t byte = 0; byte < blob.size(); ++byte) {
    for (int bit = 0; bit < 8; ++bit) {
      blob[byte] ^= std::byte(1u << bit);
      // Header and table flips must be refused by open itself, payload flips at least by verify.
      const std::string error =
          byte < table_end ? test::open_only(blob) : test::open_and_verify(blob);
      blob[byte] ^= std::byte(1u << bit);
      ASSERT_NE(error, "") << "flip of bit " << bit << " at byte " << byte << " went unnoticed";
    }
  }
}

TEST(Corruption, FlipsInCompressedSectionsAreCaught) {
  KILN_REQUIRE_CORPUS();
  auto blob = small_blob(true, "classic/teapot.obj");
  const auto header = header_of(blob);
  bool any_compressed = false;
  for (std::uint32_t s = 0; s < header.section_count; ++s) {
    const auto e = entry_of(blob, s);
    if (e.codec != std::uint8_t(format::Codec::kZstd)) continue;
    any_compressed = true;
    for (std::uint64_t byte = e.offset; byte < e.offset + e.stored_size; byte += 13) {
      blob[byte] ^= std::byte(0x10);
      const std::string error = test::open_and_verify(blob);
      blob[byte] ^= std::byte(0x10);
      ASSERT_NE(error, "") << "section " << s << " byte " << byte;
    }
  }
  EXPECT_TRUE(any_compressed);
}

TEST(Corruption, WrongIdentifierAndTextModeDamage) {
  KILN_REQUIRE_CORPUS();
  auto blob = small_blob();
  auto png = blob;
  const unsigned char png_magic[] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  std::memcpy(png.data(), png_magic, sizeof(png_magic));
  EXPECT_NE(test::open_only(png).find("not a kiln blob"), std::string::npos);

  // A text-mode transfer turns CR LF into LF: the identifier is the first thing to notice.
  std::vector<std::byte> text_mode;
  for (std::size_t i = 0; i < blob.size(); ++i) {
    if (blob[i] == std::byte('\r') && i + 1 < blob.size() && blob[i + 1] == std::byte('\n'))
      continue;
    text_mode.push_back(blob[i]);
  }
  EXPECT_NE(test::open_only(text_mode).find("text-mode"), std::string::npos)
      << test::open_only(text_mode);
}

TEST(Corruption, ForgedVersionsAreRefused) {
  KILN_REQUIRE_CORPUS();
  auto blob = small_blob();
  auto h = header_of(blob);
  h.version_major = format::kVersionMajor + 1;
  auto newer_major = blob;
  forge(newer_major, h);
  EXPECT_NE(test::open_only(newer_major).find("major version"), std::string::npos);

  h = header_of(blob);
  h.version_minor = format::kVersionMinor + 1;
  auto newer_minor = blob;
  forge(newer_minor, h);
  EXPECT_NE(test::open_only(newer_minor).find("newer"), std::string::npos);

  // A format 1.x blob (before the structure registry) is refused with the way out, in one line.
  ASSERT_EQ(format::kVersionMajor, 2);
  h = header_of(blob);
  h.version_major = 1;
  h.version_minor = 3;
  auto older_major = blob;
  forge(older_major, h);
  const std::string error = test::open_only(older_major);
  EXPECT_NE(error.find("format 1.3 blob"), std::string::npos) << error;
  EXPECT_NE(error.find("rebuild it with kiln build"), std::string::npos) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos) << error;
}

TEST(Corruption, AbsurdCountsWithValidChecksumsAreRefused) {
  KILN_REQUIRE_CORPUS();
  const auto blob = small_blob();
  {
    auto forged = blob;
    auto h = header_of(forged);
    h.section_count = 0xFFFFFFFFu;
    forge(forged, h);
    EXPECT_NE(test::open_only(forged).find("section count"), std::string::npos)
        << test::open_only(forged);
  }
  {
    auto forged = blob;
    auto h = header_of(forged);
    h.section_table_offset = ~std::uint64_t{0} - 7;
    forge(forged, h);
    EXPECT_NE(test::open_only(forged), "");
  }
  const std::uint32_t positions = 1;
  {
    auto forged = blob;
    auto e = entry_of(forged, positions);
    e.element_count = ~std::uint64_t{0} / 2;  // count x size overflows 64 bits
    forge_entry(forged, positions, e);
    EXPECT_NE(test::open_only(forged).find("element count"), std::string::npos);
  }
  {
    auto forged = blob;
    auto e = entry_of(forged, positions);
    e.offset = ~std::uint64_t{0} - 63;  // offset + size wraps around
    forge_entry(forged, positions, e);
    EXPECT_NE(test::open_only(forged), "");
  }
  {
    auto forged = blob;
    auto e = entry_of(forged, positions);
    e.offset = entry_of(forged, 0).offset;  // overlaps the manifest
    forge_entry(forged, positions, e);
    EXPECT_NE(test::open_only(forged).find("overlaps"), std::string::npos);
  }
  {
    // Consistent entry, but fewer vertices than the manifest claims.
    auto forged = blob;
    auto e = entry_of(forged, positions);
    e.element_count -= 1;
    e.raw_size -= 12;
    e.stored_size -= 12;
    forge_entry(forged, positions, e);
    EXPECT_NE(test::open_only(forged), "");
  }
}

TEST(Corruption, DeepCheckCatchesOutOfRangeIndicesWithValidChecksums) {
  KILN_REQUIRE_CORPUS();
  auto blob = small_blob();
  auto tris = entry_of(blob, 2);
  ASSERT_EQ(tris.kind, format::kSectionTriangles);
  const std::uint32_t absurd = 0x7FFFFFFF;
  std::memcpy(blob.data() + tris.offset, &absurd, 4);
  tris.checksum = xxh3_64(std::span<const std::byte>(blob).subspan(tris.offset, tris.stored_size));
  forge_entry(blob, 2, tris);
  EXPECT_EQ(test::open_only(blob), "");  // open is O(sections): it cannot see this
  EXPECT_NE(test::open_and_verify(blob).find("names vertex"), std::string::npos);
}

TEST(Corruption, UnknownSectionKindsAreSkippedUnlessRequired) {
  KILN_REQUIRE_CORPUS();
  const Scene scene = import_scene({test::mesh_path("assimp/OBJ/box.obj")}, 1);
  const std::vector<std::byte> geometry = compile_blob(scene, {});
  // Re-serialise the same sections plus one a newer tool might write.
  const auto header = header_of(geometry);
  std::vector<SectionPayload> sections;
  for (std::uint32_t s = 0; s < header.section_count; ++s) {
    const auto e = entry_of(geometry, s);
    sections.push_back({e.kind, e.flags, e.element_size, e.element_count,
                        std::span<const std::byte>(geometry).subspan(e.offset, e.stored_size),
                        false});
  }
  const std::vector<std::byte> extra(100, std::byte{7});
  sections.push_back({format::fourcc('X', 'T', 'R', 'A'), 0, 1, extra.size(), extra, false});
  EXPECT_EQ(test::open_and_verify(serialize_blob(sections, {}, 1)), "");
  sections.back().flags = std::uint16_t(format::SectionFlag::kRequired);
  EXPECT_NE(test::open_only(serialize_blob(sections, {}, 1)).find("REQUIRED"), std::string::npos);
}

}  // namespace
}  // namespace kiln
