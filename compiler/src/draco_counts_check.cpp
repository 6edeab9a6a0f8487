// Draco (1.5.5) sizes its corner table and attribute arrays from the counts in a stream's header
// before reading the data they describe, so a 100-byte stream claiming 10^8 faces makes it
// allocate gigabytes (found by import_drc_fuzzer). This reads those counts first, the way the
// decoder does, and refuses counts no stream of this size could encode.
#include "draco_counts_check.hpp"

#include <cstdint>
#include <cstring>
#include <string>

#include "kiln/compiler/import.hpp"

namespace kiln {

namespace {

// Far beyond any real compression (Edgebreaker spends bits per face, positions bytes per
// vertex), and small enough that what Draco allocates stays bounded by the input's size.
constexpr std::uint64_t kMaxElementsPerByte = 1024;
constexpr std::uint64_t kMinBudgetBytes = 4096;
constexpr int kMaxMetadataDepth = 32;

class Reader {
 public:
  Reader(const std::string& path, std::span<const std::byte> bytes) : path_(path), bytes_(bytes) {}
  [[noreturn]] void fail(const std::string& what) const {
    throw ImportError(path_ + ": Draco: " + what);
  }
  std::uint64_t u(std::size_t size) {
    if (bytes_.size() - pos_ < size) fail("the stream ends inside its header");
    std::uint64_t v = 0;
    for (std::size_t i = 0; i < size; ++i) v |= std::uint64_t(bytes_[pos_ + i]) << (8 * i);
    pos_ += size;
    return v;
  }
  std::uint64_t varint() {  // LEB128, at most 5 bytes for a 32-bit count
    std::uint64_t v = 0;
    for (int shift = 0; shift < 35; shift += 7) {
      const std::uint64_t b = u(1);
      v |= (b & 0x7F) << shift;
      if ((b & 0x80) == 0) return v;
    }
    fail("a count in its header is not a valid varint");
  }
  void skip(std::uint64_t size) {
    if (bytes_.size() - pos_ < size) fail("the stream ends inside its metadata");
    pos_ += std::size_t(size);
  }

 private:
  std::string path_;
  std::span<const std::byte> bytes_;
  std::size_t pos_ = 0;
};

void skip_metadata(Reader& in, int depth) {
  if (depth > kMaxMetadataDepth) in.fail("metadata nested too deep");
  for (std::uint64_t entries = in.varint(); entries > 0; --entries) {
    in.skip(in.u(1));      // key
    in.skip(in.varint());  // value
  }
  for (std::uint64_t subs = in.varint(); subs > 0; --subs) {
    in.skip(in.u(1));  // key
    skip_metadata(in, depth + 1);
  }
}

void skip_geometry_metadata(Reader& in) {
  for (std::uint64_t attributes = in.varint(); attributes > 0; --attributes) {
    in.varint();  // the attribute's unique id
    skip_metadata(in, 0);
  }
  skip_metadata(in, 0);  // the file's own
}

}  // namespace

void check_draco_counts(const std::string& path, std::span<const std::byte> bytes) {
  Reader in(path, bytes);
  if (bytes.size() < 5 || std::memcmp(bytes.data(), "DRACO", 5) != 0) return;  // Draco says why
  in.skip(5);
  const auto major = in.u(1), minor = in.u(1), type = in.u(1), method = in.u(1);
  const auto flags = in.u(2);
  // Edgebreaker counts became varints in 2.0, sequential ones in 2.2.
  const bool v20 = major >= 2, v22 = major > 2 || (major == 2 && minor >= 2);
  auto count = [&](bool varint) { return varint ? in.varint() : in.u(4); };
  if ((flags & 0x8000) != 0) skip_geometry_metadata(in);
  const std::uint64_t budget =
      kMaxElementsPerByte * std::max<std::uint64_t>(bytes.size(), kMinBudgetBytes);
  auto bound = [&](std::uint64_t n, const char* what) {
    if (n > budget)
      in.fail("claims " + std::to_string(n) + " " + what + ", more than a stream of " +
              std::to_string(bytes.size()) + " bytes can encode");
  };
  if (type == 0) {  // a point cloud: sequential and k-d tree both start with the point count
    bound(in.u(4), "points");
  } else if (type == 1 && method == 0) {  // sequential mesh
    bound(count(v22), "faces");
    bound(count(v22), "points");
  } else if (type == 1 && method == 1) {  // Edgebreaker
    in.u(1);                              // traversal decoder type
    if (!v22) bound(count(v20), "new vertices");
    bound(count(v20), "vertices");
    bound(count(v20), "faces");
    in.u(1);  // attribute data count
    bound(count(v20), "symbols");
    bound(count(v20), "split symbols");
  }
}

}  // namespace kiln
