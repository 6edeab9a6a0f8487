// Inputs the blob fuzzers found (tests/fuzz/regressions/) and their seeds (tests/fuzz/corpus/blob/)
// go through exactly what blob_fuzzer does with an input (tests/fuzz/blob_exercise.hpp): open,
// every structure's view and queries, verify. Each must be refused with a BlobError or accepted,
// never crash or throw anything else (the suite also runs under ASan + UBSan); every seed must
// be accepted.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "fuzz/blob_exercise.hpp"
#include "fuzz/import_exercise.hpp"
#include "kiln/runtime/aligned_buffer.hpp"
#include "kiln/runtime/esvo.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

namespace fs = std::filesystem;

AlignedBuffer read_aligned(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  const std::vector<char> bytes((std::istreambuf_iterator<char>(in)),
                                std::istreambuf_iterator<char>());
  AlignedBuffer buffer(bytes.size(), 64);
  if (!bytes.empty()) std::memcpy(buffer.data(), bytes.data(), bytes.size());
  return buffer;
}

std::vector<fs::path> files_in(const fs::path& dir) {
  std::vector<fs::path> files;
  if (fs::is_directory(dir))
    for (const auto& entry : fs::directory_iterator(dir))
      if (entry.is_regular_file() && entry.path().filename().string().front() != '.')
        files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  return files;
}

TEST(FuzzRegression, ReproducersAreRefusedOrAnsweredNeverCrash) {
  for (const fs::path& file : files_in(fs::path(KILN_FUZZ_DIR) / "regressions")) {
    SCOPED_TRACE(file.string());
    const AlignedBuffer bytes = read_aligned(file);
    EXPECT_NO_THROW((void)fuzz::open_query_verify(bytes.bytes()));
  }
}

TEST(FuzzRegression, SeedsAreAccepted) {
  const auto seeds = files_in(fs::path(KILN_FUZZ_DIR) / "corpus" / "blob");
  ASSERT_FALSE(seeds.empty());
  for (const fs::path& file : seeds) {
    SCOPED_TRACE(file.string());
    const AlignedBuffer bytes = read_aligned(file);
    std::vector<std::string> refusals;
    EXPECT_EQ(fuzz::open_query_verify(bytes.bytes(), &refusals), "");
    EXPECT_TRUE(refusals.empty()) << refusals.front();
  }
}

// The importer targets: corpus/<format>/ seeds and regressions/<format>/ reproducers, each imported
// as that format's fuzzer imports it. Reproducers must be refused in one line or imported, never
// crash or throw anything else; every seed must import.
const std::pair<const char*, const char*> kImportTargets[] = {
    {"obj", ".obj"},     {"ply", ".ply"},         {"stl", ".stl"},
    {"gltf", ".gltf"},   {"glb", ".glb"},         {"drc", ".drc"},
    {"zst", ".ply.zst"}, {"geojson", ".geojson"}, {"csv", ".csv"},
};

TEST(FuzzRegression, ImporterSeedsImportAndReproducersAreRefusedOrImported) {
  for (const auto& [format, extension] : kImportTargets) {
    const auto seeds = files_in(fs::path(KILN_FUZZ_DIR) / "corpus" / format);
    EXPECT_FALSE(seeds.empty()) << format;
    for (const fs::path& file : seeds) {
      SCOPED_TRACE(file.string());
      const auto bytes = test::read_file(file.string());
      EXPECT_EQ(fuzz::import_and_assemble(extension, bytes), "");
    }
    for (const fs::path& file : files_in(fs::path(KILN_FUZZ_DIR) / "regressions" / format)) {
      SCOPED_TRACE(file.string());
      const auto bytes = test::read_file(file.string());
      EXPECT_NO_THROW((void)fuzz::import_and_assemble(extension, bytes));
    }
  }
}

// The cast behind esvo-huge-voxel-size-nan-cast: a direction so small against the grid that the
// slab coefficients overflow used to make NaN distances (a float-to-int conversion of NaN, UB)
// instead of a miss. Also a grid so large against float range that the same happens for unit
// directions, which Blob-level checks now refuse.
TEST(FuzzRegression, EsvoRaysTooSlowToCrossTheGridMiss) {
  const AlignedBuffer bytes = read_aligned(fs::path(KILN_FUZZ_DIR) / "corpus" / "blob" / "esvo");
  const Blob blob = Blob::open_memory(bytes.bytes());
  const EsvoView view = EsvoView::from_blob(blob);
  const float inf = INFINITY;
  EXPECT_TRUE(view.intersect({{-3, 0.1f, 0.2f}, 0, {1, 0, 0}, inf}).hit());  // the octahedron
  // Crossing the grid needs t > 2^104 below an octree-space direction of 2^-104: a miss.
  EXPECT_TRUE(view.intersect({{-3, 0.1f, 0.2f}, 0, {1e-25f, 0, 0}, inf}).hit());
  for (const float tiny : {1e-33f, 1e-40f})
    EXPECT_FALSE(view.intersect({{-3, 0.1f, 0.2f}, 0, {tiny, 0, 0}, inf}).hit()) << tiny;
}

}  // namespace
}  // namespace kiln
