// `kiln build` when the output or the cache cannot be written: a file size limit, a full file
// system, a read-only folder, a folder that is a file. The output's trouble fails the build with
// one line naming the file, leaves the previous blob as it was and no temporary behind; the
// cache's trouble is a warning on a build that succeeds.
#include <sched.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <functional>

#include "fault_support.hpp"

namespace kiln {
namespace {

namespace fs = std::filesystem;

std::size_t line_count(const std::string& text) {
  return std::size_t(std::count(text.begin(), text.end(), '\n'));
}

// A folder `out` holding the previous blob (of a small grid) and a bigger grid to build over it.
struct Fixture {
  test::TempDir dir;
  std::string out_dir = dir.file("out"), out = dir.file("out/scene.kiln");
  std::string small = dir.file("small.ply"), big = dir.file("big.ply"), cache = dir.file("cache");
  std::vector<std::byte> previous;

  Fixture() {
    fs::create_directory(out_dir);
    test::write_grid_ply(small, 40, 0.5f);
    test::write_grid_ply(big, 120, 0.25f);
    EXPECT_EQ(run({"build", small, "-o", out}).exit_code, 0);
    previous = test::read_file(out);
  }
  test::CommandResult run(const std::vector<std::string>& args,
                          const test::KilnLimits& limits = {}) const {
    return test::run_kiln_args(args, dir.path().string(), limits);
  }
  std::vector<std::string> build_big(const std::string& output) const {
    return {"build", big, "-o", output, "--accel", "bvh", "--cache-dir", cache};
  }
  // The failure `kiln build` must report: one line naming the output and saying `what`, the
  // previous blob untouched, no temporary left in the output's folder or the cache.
  void expect_clean_failure(const test::CommandResult& result, const std::string& what) const {
    EXPECT_NE(result.exit_code, 0);
    EXPECT_EQ(result.signal, 0) << "killed by signal " << result.signal;
    EXPECT_EQ(line_count(result.err), 1u) << result.err;
    EXPECT_NE(result.err.find(out), std::string::npos) << result.err;
    EXPECT_NE(result.err.find(what), std::string::npos) << result.err;
    EXPECT_TRUE(test::read_file(out) == previous);
    EXPECT_EQ(test::temporaries_in(dir.path().string()), std::vector<std::string>{});
  }
};

TEST(BuildWriteErrors, FileSizeLimitFailsWithOneLineAndKeepsThePreviousBlob) {
  Fixture f;
  const std::string clean = f.dir.file("clean.kiln");
  ASSERT_EQ(f.run({"build", f.big, "-o", clean, "--accel", "bvh"}).exit_code, 0);
  const auto size = fs::file_size(clean);
  ASSERT_GT(size, 2 * f.previous.size());
  // Under `ulimit -f` a write past the limit raises SIGXFSZ, which would kill kiln before it
  // could remove its temporary or say why: kiln ignores it and reports EFBIG.
  test::KilnLimits limits;
  limits.max_file_bytes = size / 2;
  const auto limited = f.run(f.build_big(f.out), limits);
  f.expect_clean_failure(limited, "File too large");
  // Nothing was cached either: the same build without the limit is a miss giving clean bytes.
  const auto unlimited = f.run(f.build_big(f.out));
  ASSERT_EQ(unlimited.exit_code, 0) << unlimited.err;
  EXPECT_EQ(unlimited.err.find("cache hit"), std::string::npos) << unlimited.err;
  EXPECT_TRUE(test::read_file(f.out) == test::read_file(clean));
}

// Root writes into a read-only folder regardless of its mode: kiln runs as nobody then.
TEST(BuildWriteErrors, ReadOnlyFolderFailsWithOneLineAndKeepsThePreviousBlob) {
  Fixture f;
  ASSERT_EQ(f.run(f.build_big(f.dir.file("warm.kiln"))).exit_code, 0);  // a hit is possible
  fs::permissions(f.dir.path(), fs::perms::owner_all | fs::perms::group_exec |
                                    fs::perms::group_read | fs::perms::others_exec |
                                    fs::perms::others_read);
  fs::permissions(f.out_dir, fs::perms::all & ~(fs::perms::owner_write | fs::perms::group_write |
                                                fs::perms::others_write));
  test::KilnLimits nobody;
  nobody.unprivileged = true;
  for (const bool cached : {false, true}) {
    auto args = f.build_big(f.out);
    if (!cached) args.resize(args.size() - 2);
    const auto result = f.run(args, nobody);
    if (result.exit_code == 126) GTEST_SKIP() << "cannot drop root's privileges here";
    SCOPED_TRACE(cached ? "through a warm cache" : "without a cache");
    f.expect_clean_failure(result, "Permission denied");
  }
  fs::permissions(f.out_dir, fs::perms::owner_write, fs::perm_options::add);
}

TEST(BuildWriteErrors, FolderThatIsAFileFailsWithOneLine) {
  Fixture f;
  const std::string file = f.dir.file("out/not-a-folder");
  test::write_text(file, "text");
  f.out = file + "/scene.kiln";
  const auto result = f.run(f.build_big(f.out));
  EXPECT_NE(result.exit_code, 0);
  EXPECT_EQ(line_count(result.err), 1u) << result.err;
  EXPECT_NE(result.err.find(f.out), std::string::npos) << result.err;
  EXPECT_NE(result.err.find("Not a directory"), std::string::npos) << result.err;
  EXPECT_EQ(test::read_text(file), "text");
  EXPECT_EQ(test::temporaries_in(f.dir.path().string()), std::vector<std::string>{});
}

// Fails only at the rename, after every byte was written: the temporary must go all the same.
TEST(BuildWriteErrors, OutputThatIsAFolderFailsWithOneLineAndNoTemporary) {
  Fixture f;
  fs::remove(f.out);
  fs::create_directory(f.out);
  test::write_text(f.out + "/keep", "text");
  const auto result = f.run(f.build_big(f.out));
  EXPECT_NE(result.exit_code, 0);
  EXPECT_EQ(line_count(result.err), 1u) << result.err;
  EXPECT_NE(result.err.find(f.out), std::string::npos) << result.err;
  EXPECT_EQ(test::read_text(f.out + "/keep"), "text");
  EXPECT_EQ(test::temporaries_in(f.dir.path().string()), std::vector<std::string>{});
}

// Runs `body` in a child process with a private mount namespace where `folder` is a fresh tmpfs
// of `bytes`: a full disk without filling the machine's. False (the test skips) where mounting
// is not allowed. What the body finds must go to files outside `folder`.
bool on_small_tmpfs(const std::string& folder, std::size_t bytes,
                    const std::function<void()>& body) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    const std::string size = "size=" + std::to_string(bytes);
    if (::unshare(CLONE_NEWNS) != 0 ||
        ::mount(nullptr, "/", nullptr, MS_REC | MS_PRIVATE, nullptr) != 0 ||
        ::mount("tmpfs", folder.c_str(), "tmpfs", 0, size.c_str()) != 0)
      ::_exit(77);
    body();
    ::_exit(0);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) && WEXITSTATUS(status) == 0;
}

// Records a kiln run as files in `folder`: NAME.exit and NAME.err.
void record(const test::CommandResult& result, const std::string& folder, const std::string& name) {
  test::write_text(folder + "/" + name + ".exit",
                   std::to_string(result.exit_code) + " " + std::to_string(result.signal));
  test::write_text(folder + "/" + name + ".err", result.err);
}

TEST(BuildWriteErrors, FullDiskFailsWithOneLineAndKeepsThePreviousBlob) {
  Fixture f;
  const std::string report = f.dir.file("report");
  fs::create_directory(report);
  const bool mounted = on_small_tmpfs(f.out_dir, f.previous.size() + (64u << 10), [&] {
    test::write_file(f.out, f.previous);
    record(f.run(f.build_big(f.out)), report, "full");
    fs::copy_file(f.out, report + "/after.kiln");
    std::string listing;
    for (const auto& entry : fs::directory_iterator(f.out_dir))
      listing += entry.path().filename().string() + "\n";
    test::write_text(report + "/listing", listing);
  });
  if (!mounted) GTEST_SKIP() << "cannot mount a small tmpfs here (needs CAP_SYS_ADMIN)";
  EXPECT_EQ(test::read_text(report + "/full.exit"), "1 0");
  const std::string err = test::read_text(report + "/full.err");
  EXPECT_EQ(line_count(err), 1u) << err;
  EXPECT_NE(err.find(f.out + ": write failed: No space left on device"), std::string::npos) << err;
  EXPECT_TRUE(test::read_file(report + "/after.kiln") == f.previous);
  EXPECT_EQ(test::read_text(report + "/listing"), "scene.kiln\n");  // no temporary
}

// The cache is a help, not a requirement: a full disk while storing an entry is a warning, the
// build succeeds with the right blob, no temporary stays in the cache and what it held still
// serves hits.
TEST(BuildWriteErrors, FullCacheDiskIsAWarningAndTheCacheStaysSound) {
  Fixture f;
  const std::string clean = f.dir.file("clean.kiln"), report = f.dir.file("report");
  ASSERT_EQ(f.run({"build", f.big, "-o", clean, "--accel", "bvh"}).exit_code, 0);
  fs::create_directory(report);
  fs::create_directory(f.cache);
  const auto small_args = [&](const std::string& output) {
    return std::vector<std::string>{"build", f.small, "-o", output, "--cache-dir", f.cache};
  };
  const bool mounted = on_small_tmpfs(f.cache, 2 * f.previous.size() + (64u << 10), [&] {
    record(f.run(small_args(f.dir.file("small1.kiln"))), report, "small1");
    record(f.run(f.build_big(f.out)), report, "big");
    fs::copy_file(f.out, report + "/big.kiln");
    test::write_text(report + "/temporaries", std::to_string(test::temporaries_in(f.cache).size()));
    record(f.run(small_args(f.dir.file("small2.kiln"))), report, "small2");
  });
  if (!mounted) GTEST_SKIP() << "cannot mount a small tmpfs here (needs CAP_SYS_ADMIN)";
  EXPECT_EQ(test::read_text(report + "/small1.exit"), "0 0");
  EXPECT_EQ(test::read_text(report + "/big.exit"), "0 0");
  const std::string err = test::read_text(report + "/big.err");
  EXPECT_EQ(line_count(err), 1u) << err;
  EXPECT_NE(err.find("warning: result not cached: " + f.cache), std::string::npos) << err;
  EXPECT_NE(err.find("No space left on device"), std::string::npos) << err;
  EXPECT_TRUE(test::read_file(report + "/big.kiln") == test::read_file(clean));
  EXPECT_EQ(test::read_text(report + "/temporaries"), "0");
  EXPECT_NE(test::read_text(report + "/small2.err").find("cache hit"), std::string::npos);
  EXPECT_TRUE(test::read_file(f.dir.file("small2.kiln")) == f.previous);
}

}  // namespace
}  // namespace kiln
