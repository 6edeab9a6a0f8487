// libFuzzer harness: a blob from memory. Opens the bytes as a blob, opens every structure it
// lists and asks each capability a few bounded queries, then runs the deep verify. A BlobError
// is the expected answer to bad bytes; any other exception, a crash or a sanitizer report is a
// finding.
//
// Built twice (tests/fuzz/CMakeLists.txt): blob_fuzzer mutates bytes blindly, so a mutant of the
// header or section table dies at its checksum (Blob::open) and a payload mutant at the section
// checksums (verify); blob_fuzzer_structured (KILN_FUZZ_STRUCTURED) adds a custom mutator that
// recomputes the section, section-table and header checksums (and the file size) after each
// mutation, so mutants of the container reach the manifest checks, the views and verify's deep
// checks. The work per input lives in blob_exercise.hpp, shared with the regression test.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <span>
#include <string>
#include <vector>

#include "blob_exercise.hpp"
#include "kiln/formats/container.hpp"
#include "kiln/runtime/aligned_buffer.hpp"
#include "kiln/runtime/checksum.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // KILN_FUZZ_VERBOSE=1 prints each refusal (to see why inputs stop where they do).
  static const bool verbose = std::getenv("KILN_FUZZ_VERBOSE") != nullptr;
  // Blobs are mapped on page boundaries; sections are aligned to 64 bytes at least.
  kiln::AlignedBuffer buffer(size, 64);
  if (size != 0) std::memcpy(buffer.data(), data, size);
  try {
    std::vector<std::string> refusals;
    const std::string refused = kiln::fuzz::open_query_verify(buffer.bytes(), &refusals);
    if (verbose) {
      for (const std::string& r : refusals) std::fprintf(stderr, "blob_fuzzer: %s\n", r.c_str());
      if (!refused.empty()) std::fprintf(stderr, "blob_fuzzer: %s\n", refused.c_str());
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "blob_fuzzer: unexpected exception (not BlobError): %s\n", e.what());
    std::abort();
  }
  return 0;
}
#ifdef KILN_FUZZ_STRUCTURED

extern "C" std::size_t LLVMFuzzerMutate(std::uint8_t* data, std::size_t size, std::size_t max_size);

namespace {

// Recomputes what the container checksums: each section's stored bytes (where the entry lies in
// the data), the section table and the header, as tests/test_support.cpp with_patched_section
// does. Leaves bytes that do not parse as a header and section table alone.
void fix_checksums(std::uint8_t* data, std::size_t size) {
  using kiln::format::FileHeader;
  using kiln::format::SectionEntry;
  if (size < sizeof(FileHeader)) return;
  FileHeader h;
  std::memcpy(&h, data, sizeof h);
  const std::uint64_t table = h.section_table_offset;
  const std::uint64_t count = h.section_count;
  if (table > size || count > (size - table) / sizeof(SectionEntry)) return;
  const std::span<const std::byte> bytes(reinterpret_cast<const std::byte*>(data), size);
  for (std::uint64_t i = 0; i < count; ++i) {
    SectionEntry e;
    std::uint8_t* at = data + table + i * sizeof(SectionEntry);
    std::memcpy(&e, at, sizeof e);
    if (e.offset > size || e.stored_size > size - e.offset) continue;
    e.checksum = kiln::xxh3_64(bytes.subspan(e.offset, e.stored_size));
    std::memcpy(at, &e, sizeof e);
  }
  h.file_size = size;  // insertions and erasures keep the declared size right
  h.section_table_checksum = kiln::xxh3_64(bytes.subspan(table, count * sizeof(SectionEntry)));
  h.header_checksum = 0;
  std::memcpy(data, &h, sizeof h);
  h.header_checksum = kiln::xxh3_64(bytes.first(kiln::format::kHeaderChecksummedBytes));
  std::memcpy(data, &h, sizeof h);
}

}  // namespace

extern "C" std::size_t LLVMFuzzerCustomMutator(std::uint8_t* data, std::size_t size,
                                               std::size_t max_size, unsigned int /*seed*/) {
  const std::size_t mutated = LLVMFuzzerMutate(data, size, max_size);
  fix_checksums(data, mutated);
  return mutated;
}

#endif  // KILN_FUZZ_STRUCTURED
