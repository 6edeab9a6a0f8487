#include "test_support.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/structure_builder.hpp"
#include "kiln/runtime/aligned_buffer.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/checksum.hpp"
#include "kiln/runtime/error.hpp"

namespace kiln::test {

std::string mesh_path(const std::string& relative) {
  return (std::filesystem::path(KILN_MESH_DIR) / relative).string();
}

bool corpus_present() {
  return std::filesystem::is_directory(KILN_MESH_DIR);
}

TempDir::TempDir() {
  std::string pattern = (std::filesystem::temp_directory_path() / "kiln-test-XXXXXX").string();
  if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
  path_ = pattern;
}

TempDir::~TempDir() {
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

std::vector<std::byte> read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(in)), {});
  std::vector<std::byte> bytes(text.size());
  if (!text.empty()) std::memcpy(bytes.data(), text.data(), text.size());  // no memcpy from null
  return bytes;
}

void write_file(const std::string& path, std::span<const std::byte> bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

std::string read_text(const std::string& path) {
  const auto bytes = read_file(path);
  return {reinterpret_cast<const char*>(bytes.data()), bytes.size()};
}

void write_text(const std::string& path, const std::string& text) {
  write_file(path, std::as_bytes(std::span<const char>(text.data(), text.size())));
}

namespace {

std::string open_impl(std::span<const std::byte> bytes, bool verify) {
  AlignedBuffer copy(bytes.size(), 64);
  if (!bytes.empty()) std::memcpy(copy.data(), bytes.data(), bytes.size());
  try {
    const Blob blob = Blob::open_memory(copy.bytes(), "test.kiln");
    if (verify) blob.verify();
  } catch (const BlobError& e) {
    const std::string message = e.what();
    return message.empty() ? "empty error message" : message;
  }
  return {};
}

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace

std::vector<std::byte> blob_with(const Scene& scene, std::string_view spec, unsigned threads,
                                 bool compress) {
  BuildOptions options;
  options.inputs = {"generated"};
  options.threads = threads;
  options.compression.enabled = compress;
  options.structures.push_back(resolve_structure_request(spec, {}));
  return compile_blob(scene, options);
}

std::string open_and_verify(std::span<const std::byte> bytes) {
  return open_impl(bytes, true);
}
std::string open_only(std::span<const std::byte> bytes) {
  return open_impl(bytes, false);
}

CommandResult run_kiln(const std::string& arguments) {
  TempDir dir;
  const std::string out = dir.file("stdout"), err = dir.file("stderr");
  const std::string command =
      std::string("'") + KILN_CLI + "' " + arguments + " >'" + out + "' 2>'" + err + "' </dev/null";
  const int status = std::system(command.c_str());
  CommandResult result;
  if (WIFEXITED(status)) {
    result.exit_code = WEXITSTATUS(status);
    // The shell reports a child killed by a signal as 128 + signal.
    if (result.exit_code > 128) result.signal = result.exit_code - 128;
  } else if (WIFSIGNALED(status)) {
    result.signal = WTERMSIG(status);
  }
  result.out = slurp(out);
  result.err = slurp(err);
  return result;
}

AlignedBuffer aligned_copy(std::span<const std::byte> bytes) {
  AlignedBuffer copy(bytes.size(), 64);
  std::memcpy(copy.data(), bytes.data(), bytes.size());
  return copy;
}

std::vector<std::byte> with_patched_section(std::vector<std::byte> blob, std::uint32_t section,
                                            std::size_t offset, std::span<const std::byte> bytes) {
  format::SectionEntry entry;
  std::memcpy(&entry, blob.data() + 64 + 64 * section, 64);
  std::memcpy(blob.data() + entry.offset + offset, bytes.data(), bytes.size());
  entry.checksum =
      xxh3_64(std::span<const std::byte>(blob).subspan(entry.offset, entry.stored_size));
  std::memcpy(blob.data() + 64 + 64 * section, &entry, 64);
  format::FileHeader h;
  std::memcpy(&h, blob.data(), 64);
  h.section_table_checksum =
      xxh3_64(std::span<const std::byte>(blob).subspan(64, 64 * h.section_count));
  h.header_checksum = 0;
  std::memcpy(blob.data(), &h, 64);
  h.header_checksum = xxh3_64(std::span<const std::byte>(blob).first(56));
  std::memcpy(blob.data(), &h, 64);
  return blob;
}

}  // namespace kiln::test
