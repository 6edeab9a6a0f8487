// A reader that mapped a blob keeps its bytes while `kiln build` replaces the file (the new blob
// is renamed over the path, never written into it); a new open sees the new blob, whole.
#include <atomic>
#include <filesystem>
#include <thread>

#include "fault_support.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/capabilities.hpp"
#include "kiln/runtime/checksum.hpp"
#include "kiln/runtime/structure_registry.hpp"

namespace kiln {
namespace {

// What a reader sees: a hash of every byte and a few closest hits straight down on the grid.
struct Answers {
  std::uint64_t bytes_hash = 0, triangles = 0;
  std::vector<std::pair<float, std::uint32_t>> hits;  // (t, triangle)
  friend bool operator==(const Answers&, const Answers&) = default;
};

Answers ask(const Blob& blob) {
  Answers answers{xxh3_64(blob.file_bytes()), blob.input().triangle_count, {}};
  const auto view = open_structure(blob, "bvh");
  for (float x = 0.05f; x < 1.0f; x += 0.1f) {
    const Hit hit = view->rays()->closest(Ray{{x, 0.5f, 5.0f}, 0.0f, {0, 0, -1}, 100.0f});
    answers.hits.emplace_back(hit.t, hit.prim);
  }
  return answers;
}

struct Fixture {
  test::TempDir dir;
  std::string a = dir.file("a.ply"), b = dir.file("b.ply"), out = dir.file("scene.kiln");
  Fixture() {
    test::write_grid_ply(a, 60, 0.5f);
    test::write_grid_ply(b, 80, 0.25f);
  }
  test::CommandResult build(const std::string& input, bool cached = false) const {
    std::vector<std::string> args{"build", input, "-o", out, "--accel", "bvh"};
    if (cached) args.insert(args.end(), {"--cache-dir", dir.file("cache")});
    return test::run_kiln_args(args, dir.path().string());
  }
};

TEST(BlobReplace, MappedBlobKeepsItsBytesWhileABuildReplacesIt) {
  Fixture f;
  ASSERT_EQ(f.build(f.a).exit_code, 0);
  const Blob old_blob = Blob::open_file(f.out);
  const Answers before = ask(old_blob);
  ASSERT_NE(before.hits[3].second, kNoHit);

  const auto rebuilt = f.build(f.b);
  ASSERT_EQ(rebuilt.exit_code, 0) << rebuilt.err;
  EXPECT_NO_THROW(old_blob.verify());
  EXPECT_TRUE(ask(old_blob) == before);

  const Blob new_blob = Blob::open_file(f.out);
  EXPECT_NO_THROW(new_blob.verify());
  const Answers after = ask(new_blob);
  EXPECT_EQ(after.triangles, 2u * 80 * 80);
  EXPECT_NE(after.bytes_hash, before.bytes_hash);
  EXPECT_FALSE(after.hits == before.hits);
}

// Builds alternate between two inputs (fresh builds, then cache hits restored by copy) while a
// reader opens the path over and over: every open is one of the two blobs, whole.
TEST(BlobReplace, ConcurrentOpensSeeOneWholeBlobOrTheOther) {
  Fixture f;
  ASSERT_EQ(f.build(f.b).exit_code, 0);
  const std::uint64_t hash_b = xxh3_64(test::read_file(f.out));
  ASSERT_EQ(f.build(f.a).exit_code, 0);
  const std::uint64_t hash_a = xxh3_64(test::read_file(f.out));
  std::atomic<bool> done{false};
  std::atomic<int> failed_builds{0};
  std::thread builder([&] {
    for (int i = 0; i < 12; ++i)
      if (f.build(i % 2 == 0 ? f.b : f.a, /*cached=*/true).exit_code != 0) ++failed_builds;
    done = true;
  });
  int opens = 0, mixed = 0;
  while (!done) {
    ++opens;
    try {
      const Blob blob = Blob::open_file(f.out);
      blob.verify();
      const std::uint64_t hash = xxh3_64(blob.file_bytes());
      mixed += hash != hash_a && hash != hash_b;
    } catch (const std::exception& e) {
      ADD_FAILURE() << e.what();
      ++mixed;
    }
  }
  builder.join();
  EXPECT_EQ(failed_builds, 0);
  EXPECT_EQ(mixed, 0) << "of " << opens << " opens";
  EXPECT_GT(opens, 0);
}

}  // namespace
}  // namespace kiln
