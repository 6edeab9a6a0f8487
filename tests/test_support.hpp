#pragma once

#include <gtest/gtest.h>

#include <cstddef>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "kiln/runtime/aligned_buffer.hpp"

namespace kiln {
struct Scene;
}

namespace kiln::test {

/// Built with AddressSanitizer: resident sizes mean nothing and tests at scale are cut.
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kSanitized = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif
#else
constexpr bool kSanitized = false;
#endif

// compile_blob of `scene` with the one structure `spec` asks for ("KIND[:key=value,...]", as
// `--accel` takes it).
std::vector<std::byte> blob_with(const Scene& scene, std::string_view spec, unsigned threads,
                                 bool compress = false);

// Absolute path of a corpus file (../shared/data/meshes/...).
std::string mesh_path(const std::string& relative);
bool corpus_present();

#define KILN_REQUIRE_CORPUS()                                                         \
  do {                                                                                \
    if (!::kiln::test::corpus_present())                                              \
      GTEST_SKIP() << "mesh corpus " KILN_MESH_DIR " is absent: corpus test skipped"; \
  } while (0)

// A fresh directory, removed with everything in it at scope exit.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  std::filesystem::path path() const { return path_; }
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  std::filesystem::path path_;
};

std::vector<std::byte> read_file(const std::string& path);
void write_file(const std::string& path, std::span<const std::byte> bytes);
// The same for text (no newline translation).
std::string read_text(const std::string& path);
void write_text(const std::string& path, const std::string& text);

// Opens a copy of `bytes` (aligned) and runs verify(); returns "" when both succeed, else the
// error message.
std::string open_and_verify(std::span<const std::byte> bytes);
// Only the open (O(sections)) checks.
std::string open_only(std::span<const std::byte> bytes);

// `blob` with `bytes` written at `offset` inside raw section `section`, and the section, table and
// header checksums recomputed: corruption that only the structural checks can catch.
std::vector<std::byte> with_patched_section(std::vector<std::byte> blob, std::uint32_t section,
                                            std::size_t offset, std::span<const std::byte> bytes);

// A 64-byte-aligned copy of `bytes`, as Blob::open_memory wants.
AlignedBuffer aligned_copy(std::span<const std::byte> bytes);

// aligned_copy of `blob` with `value`'s bytes written at `offset` inside `section`, checksums
// recomputed (with_patched_section).
template <class T>
AlignedBuffer forged_copy(const std::vector<std::byte>& blob, std::uint32_t section,
                          std::size_t offset, const T& value) {
  return aligned_copy(
      with_patched_section(blob, section, offset, std::as_bytes(std::span<const T>(&value, 1))));
}

// A path in single quotes for run_kiln's shell.
inline std::string quoted(const std::string& s) {
  return "'" + s + "'";
}

struct CommandResult {
  int exit_code = -1;  // -1 when killed by a signal
  int signal = 0;
  std::string out, err;
};
// Runs the kiln CLI with the given argument string (shell-quoted by the caller).
CommandResult run_kiln(const std::string& arguments);

}  // namespace kiln::test
