// libFuzzer harness: a blob from memory. Opens the bytes as a blob, opens every structure it
// lists and asks each capability a few bounded queries, then runs the deep verify. A BlobError
// is the expected answer to bad bytes; any other exception, a crash or a sanitizer report is a
// finding.
//
// Built twice (tests/fuzz/CMakeLists.txt): blob_fuzzer mutates bytes blindly, so most mutants
// die at the header or section checksums; blob_fuzzer_structured (KILN_FUZZ_STRUCTURED) adds a
// custom mutator that recomputes the section, section-table and header checksums after each
// mutation, so mutants reach the manifest checks, the views and the queries.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <span>
#include <vector>

#include "kiln/formats/container.hpp"
#include "kiln/runtime/aligned_buffer.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/capabilities.hpp"
#include "kiln/runtime/checksum.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/structure_registry.hpp"

namespace {

using kiln::format::Float3;

bool finite(const Float3& p) {
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
}

// The input's bounds as a usable box: a fuzzed manifest may hold anything, and the queries a
// program asks are its own business, so keep them finite and of sane magnitude.
void query_box(const kiln::Blob& blob, Float3& lo, Float3& hi) {
  lo = blob.input().bounds.min;
  hi = blob.input().bounds.max;
  const bool sane = finite(lo) && finite(hi) && lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z &&
                    std::fabs(lo.x) < 1e6f && std::fabs(lo.y) < 1e6f && std::fabs(lo.z) < 1e6f &&
                    std::fabs(hi.x) < 1e6f && std::fabs(hi.y) < 1e6f && std::fabs(hi.z) < 1e6f;
  if (!sane) {
    lo = {-1, -1, -1};
    hi = {1, 1, 1};
  }
}

void exercise(const kiln::StructureView& view, const Float3& lo, const Float3& hi) {
  const Float3 c{(lo.x + hi.x) * 0.5f, (lo.y + hi.y) * 0.5f, (lo.z + hi.z) * 0.5f};
  const Float3 ext{hi.x - lo.x + 1e-3f, hi.y - lo.y + 1e-3f, hi.z - lo.z + 1e-3f};
  const float diag = std::sqrt(ext.x * ext.x + ext.y * ext.y + ext.z * ext.z);

  if (const kiln::RayQueries* rays = view.rays()) {
    // Axis rays into the box from outside, a diagonal, one from the centre, one that misses.
    std::vector<kiln::Ray> batch;
    const float inf = INFINITY;
    batch.push_back({{lo.x - ext.x, c.y, c.z}, 0.0f, {1, 0, 0}, inf});
    batch.push_back({{c.x, hi.y + ext.y, c.z}, 0.0f, {0, -1, 0}, inf});
    batch.push_back({{c.x, c.y, lo.z - ext.z}, 0.0f, {0, 0, 1}, inf});
    batch.push_back({{lo.x - ext.x, lo.y - ext.y, lo.z - ext.z}, 0.0f, {ext.x, ext.y, ext.z}, inf});
    batch.push_back({c, 0.0f, {0.3f, -0.5f, 0.81f}, inf});
    batch.push_back({{hi.x + ext.x, hi.y + ext.y, hi.z + ext.z}, 0.0f, {1, 1, 1}, inf});
    batch.push_back({{lo.x, c.y + 0.1f * ext.y, c.z}, 0.0f, {1, 0.01f, 0}, diag * 0.5f});

    const std::size_t record = rays->record_size();
    std::vector<std::uint64_t> storage((batch.size() * record + 7) / 8 + 1);
    std::span<std::byte> records(reinterpret_cast<std::byte*>(storage.data()),
                                 batch.size() * record);
    rays->trace_records(batch, records, false, 1);
    rays->trace_records(batch, records, true, 1);
    for (const kiln::Ray& ray : batch) {
      (void)rays->closest(ray);
      kiln::Cost cost;
      (void)rays->intersect_counting(ray, cost);
    }
  }

  const Float3 points[] = {c, lo, hi, {hi.x + ext.x, lo.y - ext.y, c.z}};
  if (const kiln::SurfaceQueries* surface = view.surface()) {
    for (const Float3& p : points) {
      (void)surface->closest_point(p, INFINITY);
      (void)surface->closest_point(p, diag * 0.1f);
      (void)surface->inside(p);
    }
    std::vector<std::uint32_t> ids;
    surface->triangles_in_box(lo, c, ids);
    surface->triangles_in_box(hi, lo, ids);  // an empty (inverted) box
  }
  if (const kiln::NeighborQueries* neighbors = view.neighbors()) {
    kiln::Neighbor found[4];
    std::vector<kiln::Neighbor> within;
    for (const Float3& p : points) {
      (void)neighbors->nearest(p, found);
      neighbors->within_radius(p, diag * 0.25f, within);
    }
    (void)neighbors->nearest(c, std::span<kiln::Neighbor>(found, 0));
  }
  if (const kiln::OccupancyQueries* occupancy = view.occupancy()) {
    for (const Float3& p : points) (void)occupancy->occupied(p);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // Blobs are mapped on page boundaries; sections are aligned to 64 bytes at least.
  kiln::AlignedBuffer buffer(size, 64);
  if (size != 0) std::memcpy(buffer.data(), data, size);
  try {
    const kiln::Blob blob = kiln::Blob::open_memory(buffer.bytes(), "<fuzz>");
    Float3 lo, hi;
    query_box(blob, lo, hi);
    for (const kiln::StructureInfo& info : blob.structures()) {
      try {
        const auto view = kiln::open_structure(blob, info.name);
        if (view) exercise(*view, lo, hi);
      } catch (const kiln::BlobError&) {
        // A structure refused: the others and verify still run.
      }
    }
    blob.verify();
  } catch (const kiln::BlobError&) {
    // Expected: bad bytes refused with a reason.
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
