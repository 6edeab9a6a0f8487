// `kiln build --cache-dir`: a hit gives the very bytes a fresh build gives, and anything that
// could change those bytes (an option, a companion file, a damaged entry) is a miss.
#include <filesystem>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "import_fixtures.hpp"
#include "kiln/compiler/build_cache.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

namespace fs = std::filesystem;

using test::quoted;
using test::read_text;
using test::write_text;

// A cache folder beside one triangle coloured by `mesh.mtl` and a glTF reading `tri.bin`.
struct Fixture {
  test::TempDir dir;
  std::string cache() const { return dir.file("cache"); }
  void write_obj(const char* kd) const { test::write_obj_with_mtl(dir.path(), "mesh.mtl", kd); }
  void write_gltf(float x) const { test::write_gltf_with_bin(dir.path(), "tri.bin", x); }
  // `kiln build INPUT -o OUT ARGS`, through the cache unless `cached` is false.
  test::CommandResult build(const std::string& input, const std::string& out,
                            const std::string& args = "--accel bvh", bool cached = true) const {
    return test::run_kiln("build " + quoted(dir.file(input)) + " -o " + quoted(dir.file(out)) +
                          " " + args + (cached ? " --cache-dir " + quoted(cache()) : ""));
  }
  std::vector<std::byte> bytes(const std::string& name) const {
    return test::read_file(dir.file(name));
  }
};

bool is_hit(const test::CommandResult& result) {
  static const std::regex kHit("(^|\n)kiln build: cache hit [0-9a-f]{32}\n");
  return std::regex_search(result.err, kHit);
}

std::vector<fs::path> cached_blobs(const std::string& cache) {
  std::vector<fs::path> blobs;
  for (const auto& entry : fs::recursive_directory_iterator(fs::path(cache) / "blobs"))
    if (entry.is_regular_file() && entry.path().extension() == ".kiln") blobs.push_back(entry);
  return blobs;
}

TEST(BuildCache, SecondBuildIsAHitIdenticalToABuildWithoutCache) {
  Fixture f;
  f.write_obj("1 0 0");
  const auto first = f.build("mesh.obj", "a.kiln", "--accel bvh --stats");
  ASSERT_EQ(first.exit_code, 0) << first.err;
  EXPECT_FALSE(is_hit(first)) << first.err;
  EXPECT_TRUE(std::regex_search(first.err, std::regex("kiln build: cache miss [0-9a-f]{32}\n")))
      << first.err;
  EXPECT_TRUE(fs::exists(fs::path(f.cache()) / "CACHEDIR.TAG"));

  const auto second = f.build("mesh.obj", "b.kiln", "--accel bvh");
  ASSERT_EQ(second.exit_code, 0) << second.err;
  EXPECT_TRUE(is_hit(second)) << second.err;
  EXPECT_EQ(std::count(second.err.begin(), second.err.end(), '\n'), 1) << second.err;
  EXPECT_TRUE(f.bytes("a.kiln") == f.bytes("b.kiln"));

  ASSERT_EQ(f.build("mesh.obj", "plain.kiln", "--accel bvh", false).exit_code, 0);
  EXPECT_TRUE(f.bytes("a.kiln") == f.bytes("plain.kiln"));
  EXPECT_EQ(test::run_kiln("verify " + quoted(f.dir.file("b.kiln"))).exit_code, 0);
}

TEST(BuildCache, DepfileOnAHitListsWhatTheImportRead) {
  Fixture f;
  f.write_obj("1 0 0");
  ASSERT_EQ(
      f.build("mesh.obj", "a.kiln", "--accel bvh --depfile " + quoted(f.dir.file("a.d"))).exit_code,
      0);
  const auto hit =
      f.build("mesh.obj", "a.kiln", "--accel bvh --depfile " + quoted(f.dir.file("b.d")));
  ASSERT_TRUE(is_hit(hit)) << hit.err;
  // The same target (-o as given), the same files.
  EXPECT_TRUE(f.bytes("a.d") == f.bytes("b.d"));
  const std::string depfile = read_text(f.dir.file("b.d"));
  EXPECT_NE(depfile.find("mesh.mtl"), std::string::npos) << depfile;
}

TEST(BuildCache, ChangedOptionIsAMissButThreadsAreNot) {
  Fixture f;
  f.write_obj("1 0 0");
  ASSERT_EQ(f.build("mesh.obj", "a.kiln", "--accel bvh --threads 1").exit_code, 0);
  const auto threads = f.build("mesh.obj", "b.kiln", "--accel bvh --threads 2");
  EXPECT_TRUE(is_hit(threads)) << threads.err;
  for (const char* args : {"--accel bvh --bvh-max-leaf 2", "--accel bvh --compress",
                           "--accel bvh --accel kdtree", "--accel sbvh", "--accel bvh --stats"}) {
    const auto other = f.build("mesh.obj", "c.kiln", args);
    ASSERT_EQ(other.exit_code, 0) << other.err;
    // --stats only reports: it must not change the key either.
    EXPECT_EQ(is_hit(other), std::string(args) == "--accel bvh --stats") << args << other.err;
    ASSERT_EQ(f.build("mesh.obj", "d.kiln", args, false).exit_code, 0);
    EXPECT_TRUE(f.bytes("c.kiln") == f.bytes("d.kiln")) << args;
  }
}

// Colours reach the blob through the ESVO's per-voxel attachments.
constexpr const char* kColoured = "--accel esvo --resolution 8";

TEST(BuildCache, ChangedMtlIsAMissAndTheOldEntryStaysReachable) {
  Fixture f;
  f.write_obj("1 0 0");
  ASSERT_EQ(f.build("mesh.obj", "red.kiln", kColoured).exit_code, 0);
  f.write_obj("0 0 1");
  const auto blue = f.build("mesh.obj", "blue.kiln", kColoured);
  ASSERT_EQ(blue.exit_code, 0) << blue.err;
  EXPECT_FALSE(is_hit(blue)) << blue.err;
  EXPECT_TRUE(f.bytes("red.kiln") != f.bytes("blue.kiln"));
  ASSERT_EQ(f.build("mesh.obj", "fresh.kiln", kColoured, false).exit_code, 0);
  EXPECT_TRUE(f.bytes("blue.kiln") == f.bytes("fresh.kiln"));

  f.write_obj("1 0 0");  // back to red: the manifest keeps several entries
  const auto red_again = f.build("mesh.obj", "red2.kiln", kColoured);
  EXPECT_TRUE(is_hit(red_again)) << red_again.err;
  EXPECT_TRUE(f.bytes("red.kiln") == f.bytes("red2.kiln"));
}

TEST(BuildCache, MtlAppearingLaterIsAMiss) {
  Fixture f;
  f.write_obj("1 0 0");
  fs::remove(f.dir.path() / "mesh.mtl");
  ASSERT_EQ(f.build("mesh.obj", "plain.kiln", kColoured).exit_code, 0);
  write_text(f.dir.path() / "mesh.mtl", "newmtl red\nKd 1 0 0\n");
  const auto red = f.build("mesh.obj", "red.kiln", kColoured);
  ASSERT_EQ(red.exit_code, 0) << red.err;
  EXPECT_FALSE(is_hit(red)) << red.err;
  EXPECT_TRUE(f.bytes("plain.kiln") != f.bytes("red.kiln"));
}

TEST(BuildCache, ChangedBinIsAMiss) {
  Fixture f;
  f.write_gltf(1.0f);
  ASSERT_EQ(f.build("mesh.gltf", "a.kiln").exit_code, 0);
  EXPECT_TRUE(is_hit(f.build("mesh.gltf", "b.kiln")));
  f.write_gltf(2.0f);
  const auto changed = f.build("mesh.gltf", "c.kiln");
  ASSERT_EQ(changed.exit_code, 0) << changed.err;
  EXPECT_FALSE(is_hit(changed)) << changed.err;
  ASSERT_EQ(f.build("mesh.gltf", "d.kiln", "--accel bvh", false).exit_code, 0);
  EXPECT_TRUE(f.bytes("c.kiln") == f.bytes("d.kiln"));
  EXPECT_TRUE(f.bytes("a.kiln") != f.bytes("c.kiln"));
}

TEST(BuildCache, DamagedBlobIsDetectedAndRebuilt) {
  Fixture f;
  f.write_obj("1 0 0");
  ASSERT_EQ(f.build("mesh.obj", "good.kiln").exit_code, 0);
  const auto good = f.bytes("good.kiln");
  const auto blobs = cached_blobs(f.cache());
  ASSERT_EQ(blobs.size(), 1u);

  // A flipped byte deep in the geometry, then a truncation: both caught before OUT is replaced.
  auto flipped = good;
  flipped[flipped.size() - 100] ^= std::byte{1};
  const std::vector<std::vector<std::byte>> damages = {
      flipped, std::vector<std::byte>(good.begin(), good.begin() + good.size() / 2)};
  for (const auto& damaged : damages) {
    test::write_file(blobs[0].string(), damaged);
    const auto rebuilt = f.build("mesh.obj", "out.kiln");
    ASSERT_EQ(rebuilt.exit_code, 0) << rebuilt.err;
    EXPECT_FALSE(is_hit(rebuilt)) << rebuilt.err;
    EXPECT_NE(rebuilt.err.find("damaged; rebuilding"), std::string::npos) << rebuilt.err;
    EXPECT_TRUE(f.bytes("out.kiln") == good);
    // The rebuild stored a sound blob again.
    EXPECT_TRUE(test::read_file(blobs[0].string()) == good);
    const auto hit = f.build("mesh.obj", "again.kiln");
    EXPECT_TRUE(is_hit(hit)) << hit.err;
    EXPECT_TRUE(f.bytes("again.kiln") == good);
  }
}

TEST(BuildCache, DamagedManifestIsAMiss) {
  Fixture f;
  f.write_obj("1 0 0");
  ASSERT_EQ(f.build("mesh.obj", "good.kiln", kColoured).exit_code, 0);
  std::vector<fs::path> manifests;
  for (const auto& entry : fs::recursive_directory_iterator(fs::path(f.cache()) / "manifests"))
    if (entry.is_regular_file()) manifests.push_back(entry);
  ASSERT_EQ(manifests.size(), 1u);
  // Drop the line naming the .mtl: the checksum must make the whole manifest untrusted.
  std::string s = read_text(manifests[0].string());
  const auto mtl = s.find("read ");
  ASSERT_NE(mtl, std::string::npos);
  s.erase(mtl, s.find('\n', mtl) + 1 - mtl);
  write_text(manifests[0], s);
  EXPECT_TRUE(parse_manifest(s).empty());
  f.write_obj("0 1 0");  // trusting the rest of the entry would give the red blob
  const auto rebuilt = f.build("mesh.obj", "out.kiln", kColoured);
  ASSERT_EQ(rebuilt.exit_code, 0) << rebuilt.err;
  EXPECT_FALSE(is_hit(rebuilt)) << rebuilt.err;
  ASSERT_EQ(f.build("mesh.obj", "fresh.kiln", kColoured, false).exit_code, 0);
  EXPECT_TRUE(f.bytes("out.kiln") == f.bytes("fresh.kiln"));
}

TEST(BuildCache, ConcurrentBuildsIntoOneCacheBothSucceedIdentically) {
  Fixture f;
  f.write_obj("1 0 0");
  f.write_gltf(1.0f);
  ASSERT_EQ(f.build("mesh.obj", "plain.kiln", "--accel bvh --accel kdtree", false).exit_code, 0);
  for (int round = 0; round < 3; ++round) {
    fs::remove_all(f.cache());
    test::CommandResult results[2];
    std::thread other(
        [&] { results[1] = f.build("mesh.obj", "b.kiln", "--accel bvh --accel kdtree"); });
    results[0] = f.build("mesh.obj", "a.kiln", "--accel bvh --accel kdtree");
    other.join();
    for (const auto& result : results) {
      EXPECT_EQ(result.exit_code, 0) << result.err;
      EXPECT_EQ(result.err.find("warning"), std::string::npos) << result.err;
    }
    EXPECT_TRUE(f.bytes("a.kiln") == f.bytes("plain.kiln")) << round;
    EXPECT_TRUE(f.bytes("b.kiln") == f.bytes("plain.kiln")) << round;
    const auto hit = f.build("mesh.obj", "c.kiln", "--accel bvh --accel kdtree");
    EXPECT_TRUE(is_hit(hit)) << hit.err;
    EXPECT_TRUE(f.bytes("c.kiln") == f.bytes("plain.kiln"));
    // No temporary left behind in the cache.
    for (const auto& entry : fs::recursive_directory_iterator(f.cache()))
      EXPECT_EQ(entry.path().filename().string().find(".tmp."), std::string::npos) << entry.path();
  }
}

TEST(BuildCache, UnusableCacheDirWarnsOnceAndStillBuilds) {
  Fixture f;
  f.write_obj("1 0 0");
  write_text(f.dir.path() / "not-a-folder", "");
  const auto result = test::run_kiln("build " + quoted(f.dir.file("mesh.obj")) + " -o " +
                                     quoted(f.dir.file("a.kiln")) + " --cache-dir " +
                                     quoted(f.dir.file("not-a-folder/cache")));
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << result.err;
  EXPECT_NE(result.err.find("kiln build: warning: cache "), std::string::npos) << result.err;
  EXPECT_NE(result.err.find("building without it"), std::string::npos) << result.err;
  ASSERT_EQ(f.build("mesh.obj", "plain.kiln", "", false).exit_code, 0);
  EXPECT_TRUE(f.bytes("a.kiln") == f.bytes("plain.kiln"));
}

TEST(BuildCache, FailedBuildStoresNothingAndWritesNothing) {
  Fixture f;
  f.write_gltf(1.0f);
  fs::remove(f.dir.path() / "tri.bin");
  const auto result =
      f.build("mesh.gltf", "a.kiln", "--accel bvh --depfile " + quoted(f.dir.file("a.d")));
  EXPECT_EQ(result.exit_code, 1) << result.err;
  EXPECT_FALSE(fs::exists(f.dir.file("a.kiln")));
  EXPECT_FALSE(fs::exists(f.dir.file("a.d")));
  EXPECT_FALSE(fs::exists(fs::path(f.cache()) / "manifests"));
  EXPECT_FALSE(fs::exists(fs::path(f.cache()) / "blobs"));
}

TEST(BuildCache, ManifestRoundTripsAndRejectsDamage) {
  CacheEntry entry;
  entry.blob = {0x0123456789abcdefull, 0xfedcba9876543210ull};
  entry.blob_size = 4242;
  entry.read = {{"/a b/m#1.obj", {1, 2}}, {"/a b/m.mtl", {3, 4}}};
  entry.missing = {"/a b/other.mtl"};
  const std::vector<CacheEntry> entries = {entry, CacheEntry{}};
  const std::string text = format_manifest(entries);
  const auto parsed = parse_manifest(text);
  ASSERT_EQ(parsed.size(), 2u);
  EXPECT_EQ(parsed[0].blob, entry.blob);
  EXPECT_EQ(parsed[0].blob_size, entry.blob_size);
  EXPECT_EQ(parsed[0].read, entry.read);
  EXPECT_EQ(parsed[0].missing, entry.missing);
  EXPECT_TRUE(parsed[1].read.empty());
  for (std::size_t cut = 0; cut < text.size(); ++cut)
    EXPECT_TRUE(parse_manifest(text.substr(0, cut)).empty()) << cut;
  std::string flipped = text;
  flipped[text.find("m.mtl")] = 'n';
  EXPECT_TRUE(parse_manifest(flipped).empty());
  EXPECT_EQ(to_hex(entry.blob), "0123456789abcdeffedcba9876543210");
  EXPECT_EQ(parse_hash128("0123456789abcdeffedcba9876543210"), entry.blob);
  EXPECT_FALSE(parse_hash128("0123456789ABCDEFfedcba9876543210"));
  EXPECT_FALSE(parse_hash128("0123"));
}

}  // namespace
}  // namespace kiln
