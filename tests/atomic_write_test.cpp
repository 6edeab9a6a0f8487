// A write killed half-way leaves the output path as it was: absent, or the previous file.
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>

#include "kiln/runtime/atomic_file.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

namespace fs = std::filesystem;

// Forks a child that starts writing 64 MiB to `path` and dies by `signal_number` after the
// first chunk. Returns the child's wait status.
int write_and_die(const std::string& path, int signal_number, bool install_cleanup) {
  const pid_t child = ::fork();
  if (child == 0) {
    if (install_cleanup) install_temp_file_cleanup_on_signals();
    const std::vector<std::byte> bytes(64u << 20, std::byte{0x5A});
    write_file_atomically(path, bytes,
                          [&](std::size_t, std::size_t) { std::raise(signal_number); });
    ::_exit(0);  // not reached
  }
  int status = 0;
  ::waitpid(child, &status, 0);
  return status;
}

std::size_t entries_in(const fs::path& dir) {
  return std::size_t(std::distance(fs::directory_iterator(dir), fs::directory_iterator()));
}

TEST(AtomicWrite, KilledWriterLeavesNoFileAtTheOutputPath) {
  test::TempDir dir;
  const std::string path = dir.file("scene.kiln");
  const int status = write_and_die(path, SIGKILL, false);
  ASSERT_TRUE(WIFSIGNALED(status));
  EXPECT_EQ(WTERMSIG(status), SIGKILL);
  EXPECT_FALSE(fs::exists(path));
}

TEST(AtomicWrite, KilledWriterLeavesThePreviousFileIntact) {
  test::TempDir dir;
  const std::string path = dir.file("scene.kiln");
  const std::vector<std::byte> previous(1000, std::byte{1});
  test::write_file(path, previous);
  write_and_die(path, SIGKILL, false);
  EXPECT_EQ(test::read_file(path), previous);
}

TEST(AtomicWrite, InterruptedWriterRemovesItsTemporary) {
  test::TempDir dir;
  const std::string path = dir.file("scene.kiln");
  const int status = write_and_die(path, SIGTERM, true);
  ASSERT_TRUE(WIFSIGNALED(status));
  EXPECT_FALSE(fs::exists(path));
  EXPECT_EQ(entries_in(dir.path()), 0u);  // no stray temporary either
}

TEST(AtomicWrite, CompletedWriteHasTheBytesAndNoTemporary) {
  test::TempDir dir;
  const std::string path = dir.file("scene.kiln");
  const std::vector<std::byte> bytes(10u << 20, std::byte{9});
  write_file_atomically(path, bytes);
  EXPECT_EQ(test::read_file(path), bytes);
  EXPECT_EQ(entries_in(dir.path()), 1u);
}

TEST(AtomicWrite, UnwritableFolderThrowsAndWritesNothing) {
  EXPECT_THROW(write_file_atomically("/nonexistent-kiln-dir/x.kiln", std::vector<std::byte>(10)),
               std::runtime_error);
}

}  // namespace
}  // namespace kiln
