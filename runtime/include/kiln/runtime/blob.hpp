// A .kiln blob opened for reading: mapped (or borrowed) bytes, validated once, then handed out
// as typed zero-copy views.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "kiln/formats/container.hpp"
#include "kiln/formats/geometry.hpp"
#include "kiln/runtime/aligned_buffer.hpp"
#include "kiln/runtime/mapped_file.hpp"
#include "kiln/schema/manifest_generated.h"

namespace kiln {

inline constexpr std::uint32_t kNoSection = 0xFFFFFFFFu;

class Blob {
 public:
  // Maps `path` read-only and validates it in O(sections) (plus inflating compressed sections).
  // Throws BlobError with a one-line reason.
  static Blob open_file(const std::string& path);
  // Validates a caller-owned buffer, which must outlive the Blob and be 16-byte aligned.
  // `name` is used in error messages.
  static Blob open_memory(std::span<const std::byte> bytes, std::string name = "<memory>");
  // Non-throwing form of open_file: the reason goes to `error`.
  static std::optional<Blob> try_open_file(const std::string& path, std::string& error);

  // The deep check: every section checksum, zero padding between sections, every vertex index
  // and mesh id in range, finite positions. O(file size). Throws BlobError on the first problem.
  void verify() const;

  const std::string& name() const { return name_; }
  const format::FileHeader& header() const { return header_; }
  std::span<const format::SectionEntry> sections() const { return sections_; }
  const schema::Manifest& manifest() const { return *manifest_; }
  // The acceleration structure named `name` (its kind string), or nullptr.
  const schema::Acceleration* acceleration(std::string_view name) const;
  // The decoded bytes of a section (inflated when it was compressed).
  std::span<const std::byte> section_bytes(std::uint32_t index) const;
  std::span<const std::byte> file_bytes() const { return bytes_; }

  std::span<const format::Float3> positions() const;
  std::span<const format::Float3> normals() const;  // empty when the scene has none
  std::span<const format::Triangle> triangles() const;
  std::span<const std::uint32_t> triangle_mesh_ids() const;

  template <class T>
  std::span<const T> section_view(std::uint32_t index) const {
    if (index == kNoSection) return {};
    const auto bytes = section_bytes(index);
    return {reinterpret_cast<const T*>(bytes.data()), bytes.size() / sizeof(T)};
  }

 private:
  Blob() = default;
  void validate();
  void validate_header();
  void validate_section_table();
  void decode_sections();
  void validate_manifest();
  void validate_geometry();
  void verify_accelerations() const;
  void verify_bvh(const schema::Acceleration& accel) const;
  void verify_kdtree(const schema::Acceleration& accel) const;
  void verify_point_tree(const schema::Acceleration& accel) const;
  void verify_voxel_dag(const schema::Acceleration& accel) const;
  void verify_esvo(const schema::Acceleration& accel) const;
  [[noreturn]] void fail(const std::string& what) const;
  [[noreturn]] void fail_section(std::uint32_t index, const std::string& what) const;

  std::string name_;
  MappedFile file_;
  std::span<const std::byte> bytes_;
  format::FileHeader header_{};
  std::vector<format::SectionEntry> sections_;
  std::vector<AlignedBuffer> decoded_;  // per section; empty unless the section is compressed
  const schema::Manifest* manifest_ = nullptr;
};

}  // namespace kiln
