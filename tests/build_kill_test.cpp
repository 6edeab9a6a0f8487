// `kill -9` at moments spread over a whole `kiln build --cache-dir`: the output path always
// holds the previous blob or the complete new one, and the cache left behind still gives a blob
// byte-identical to a clean build.
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <iostream>
#include <thread>

#include "fault_support.hpp"

namespace kiln {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr int kMoments = 20;

struct KillFixture {
  test::TempDir dir;
  std::string input = dir.file("new.ply"), out = dir.file("out.kiln"), cache = dir.file("cache");
  std::vector<std::byte> old_blob, new_blob;  // the new one from a build without the cache

  std::vector<std::string> build_args(const std::string& output) const {
    return {"build", input, "-o", output, "--accel", "bvh", "--cache-dir", cache};
  }
  test::CommandResult run(const std::vector<std::string>& args) const {
    return test::run_kiln_args(args, dir.path().string());
  }
};

// Starts a build of the fixture's input to its output and kills it after `delay`.
test::CommandResult build_killed_after(const KillFixture& f, Clock::duration delay) {
  const std::string err = f.dir.file("killed.stderr");
  const pid_t pid = test::spawn_kiln(f.build_args(f.out), err);
  std::this_thread::sleep_for(delay);
  ::kill(pid, SIGKILL);
  return test::wait_kiln(pid, err);
}

// What a killed build may leave: the old blob or the new one, whole, and one `kiln verify`
// accepts; then a build through whatever cache it left gives the clean build's bytes.
void check_after_kill(const KillFixture& f, const test::CommandResult& killed, int& saw_new) {
  const auto now = test::read_file(f.out);
  const bool is_new = now == f.new_blob;
  EXPECT_TRUE(is_new || now == f.old_blob) << "a partial or foreign blob at the output path";
  if (killed.signal == 0) {
    EXPECT_TRUE(is_new) << "finished, yet the old blob: " << killed.err;
  }
  saw_new += is_new;
  const auto verify = f.run({"verify", f.out});
  EXPECT_EQ(verify.exit_code, 0) << verify.err;
  const auto again = f.run(f.build_args(f.out));
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_TRUE(test::read_file(f.out) == f.new_blob) << "the cache gave other bytes: " << again.err;
}

TEST(BuildKill, OutputIsTheOldOrTheWholeNewBlobAndTheCacheStaysSound) {
  KillFixture f;
  const std::string old_input = f.dir.file("old.ply");
  test::write_grid_ply(old_input, 80, 0.5f);
  test::write_grid_ply(f.input, 128, 0.25f);
  ASSERT_EQ(f.run({"build", old_input, "-o", f.out}).exit_code, 0);
  f.old_blob = test::read_file(f.out);
  const std::string clean = f.dir.file("clean.kiln");
  ASSERT_EQ(f.run({"build", f.input, "-o", clean, "--accel", "bvh"}).exit_code, 0);
  f.new_blob = test::read_file(clean);
  ASSERT_NE(f.old_blob, f.new_blob);

  // A whole build through an empty cache (import, compile, write, store) sets the time scale.
  const auto start = Clock::now();
  ASSERT_EQ(f.run(f.build_args(f.dir.file("timed.kiln"))).exit_code, 0);
  const auto whole = Clock::now() - start;
  int saw_new = 0;
  for (int i = 0; i < kMoments; ++i) {
    test::write_file(f.out, f.old_blob);
    // Mostly an empty cache (the kill lands in a miss and its store); every fourth moment keeps
    // the cache the last check filled (the kill lands in restoring a hit).
    if (i % 4 != 3) fs::remove_all(f.cache);
    const auto killed = build_killed_after(f, whole * i * 5 / (4 * kMoments));
    SCOPED_TRACE("moment " + std::to_string(i) + ", exit " + std::to_string(killed.exit_code) +
                 ", signal " + std::to_string(killed.signal));
    check_after_kill(f, killed, saw_new);
  }
  std::cout << "[ kill -9 ] " << kMoments << " moments over "
            << std::chrono::duration<double, std::milli>(whole).count() << " ms: " << saw_new
            << " left the new blob, " << kMoments - saw_new << " the old one, "
            << test::temporaries_in(f.dir.path().string()).size()
            << " temporaries stayed (SIGKILL leaves its temporary; no build reads one)\n";
}

}  // namespace
}  // namespace kiln
