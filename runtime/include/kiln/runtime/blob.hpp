// A .kiln blob opened for reading: mapped (or borrowed) bytes, validated once, then handed out
// as typed zero-copy views. Plain structs and spans only: the manifest's FlatBuffers types stay
// behind kiln/runtime/manifest.hpp, and structures are reached through the registry
// (kiln/runtime/structure_registry.hpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "kiln/formats/container.hpp"
#include "kiln/formats/geometry.hpp"
#include "kiln/runtime/aligned_buffer.hpp"
#include "kiln/runtime/event_table.hpp"
#include "kiln/runtime/geo_layer.hpp"
#include "kiln/runtime/input_kind.hpp"
#include "kiln/runtime/mapped_file.hpp"

namespace kiln {

inline constexpr std::uint32_t kNoSection = 0xFFFFFFFFu;

/// What the blob was built from. A point set fills the counts and bounds only.
struct InputInfo {
  InputKind kind = InputKind::kTriangles;
  std::uint64_t vertex_count = 0;  ///< vertices; a point set's point count
  std::uint64_t triangle_count = 0;
  format::Box3f bounds{{0, 0, 0}, {0, 0, 0}};  ///< over every kept vertex or point (0 if none)
  std::uint64_t input_triangle_count = 0;
  std::uint64_t degenerate_triangles_dropped = 0;
  bool has_normals = false;
  std::uint64_t boundary_edges = 0, non_manifold_edges = 0;
  bool closed = false;  ///< every edge shared by exactly two triangles
  /// A 2D input's features (polygon layer) or features/rows (point table), and its exact
  /// bounds (`bounds` holds them rounded to float, z = 0).
  std::uint64_t feature_count = 0;
  format::Box2d bounds2;
};

struct MeshInfo {
  std::string name;
  std::uint32_t source_file = 0;
  std::uint64_t first_triangle = 0, triangle_count = 0, first_vertex = 0, vertex_count = 0;
};

struct SourceInfo {
  std::string path;
  std::uint64_t size = 0, xxh3 = 0;
};

/// A structure stored in the blob: its name (unique in the blob), its kind and its sections.
struct StructureInfo {
  std::uint32_t index = 0;  ///< in the manifest's structure list
  std::string name;
  std::string kind;
  std::vector<std::uint32_t> sections;
};

class Blob {
 public:
  /// Maps `path` read-only and validates it in O(sections) (plus inflating compressed
  /// sections). Throws BlobError with a one-line reason.
  static Blob open_file(const std::string& path);
  /// Validates a caller-owned buffer, which must outlive the Blob and be 16-byte aligned.
  /// `name` is used in error messages.
  static Blob open_memory(std::span<const std::byte> bytes, std::string name = "<memory>");
  /// Non-throwing form of open_file: the reason goes to `error`.
  static std::optional<Blob> try_open_file(const std::string& path, std::string& error);

  /// The deep check: every section checksum, zero padding between sections, every vertex index
  /// and mesh id in range, finite positions, then each structure's own check. O(file size).
  /// Throws BlobError on the first problem.
  void verify() const;

  const std::string& name() const { return name_; }
  const format::FileHeader& header() const { return header_; }
  std::span<const format::SectionEntry> sections() const { return sections_; }
  /// The decoded bytes of a section (inflated when it was compressed).
  std::span<const std::byte> section_bytes(std::uint32_t index) const;
  std::span<const std::byte> file_bytes() const { return bytes_; }

  std::string tool_name() const;
  std::string tool_version() const;
  /// The recorded build options, sorted by key.
  std::vector<std::pair<std::string, std::string>> options() const;
  std::vector<SourceInfo> sources() const;
  const InputInfo& input() const { return input_; }
  std::size_t mesh_count() const;
  MeshInfo mesh(std::size_t index) const;

  std::span<const format::Float3> positions() const;    ///< vertices, or a point set's positions
  std::span<const format::Float3> normals() const;      ///< empty when the scene has none
  std::span<const format::Triangle> triangles() const;  ///< empty for a point set
  std::span<const std::uint32_t> triangle_mesh_ids() const;
  /// The 2D polygon layer this blob was built from; throws BlobError for another input kind.
  PolygonLayerView polygon_layer() const;
  /// The 2D point table this blob was built from; throws BlobError for another input kind.
  PointTableView point_table() const;
  /// The event table this blob was built from (issue 18; blob_events.cpp); throws BlobError for
  /// another input kind.
  EventTableView event_table() const;

  std::span<const StructureInfo> structures() const { return structures_; }
  /// The structure named `name`, or nullptr.
  const StructureInfo* structure(std::string_view name) const;

  template <class T>
  std::span<const T> section_view(std::uint32_t index) const {
    if (index == kNoSection) return {};
    const auto bytes = section_bytes(index);
    return {reinterpret_cast<const T*>(bytes.data()), bytes.size() / sizeof(T)};
  }

  /// Throws BlobError "<blob>: what".
  [[noreturn]] void fail(const std::string& what) const;
  /// Throws BlobError "<blob>: section N (KIND): what".
  [[noreturn]] void fail_section(std::uint32_t index, const std::string& what) const;
  /// O(1) check of a section the manifest names: in range, of `kind`, `element_size` and
  /// `count` elements; kNoSection passes when `optional`. Fails naming `what`.
  void check_section(const std::string& what, std::uint32_t index, std::uint32_t kind,
                     std::uint32_t element_size, std::uint64_t count, bool optional) const;

  /// The manifest FlatBuffer's root (a kiln::schema::Manifest): see kiln/runtime/manifest.hpp.
  const void* manifest_root() const { return manifest_; }

 private:
  Blob() = default;
  void validate();
  void validate_header();
  void validate_section_table();
  void decode_sections();
  void validate_manifest();
  void validate_input();
  void validate_structures();
  void verify_input() const;
  void validate_polygon_layer();  // blob_geo_input.cpp
  void validate_point_table();
  void verify_geo_input() const;

  std::string name_;
  MappedFile file_;
  std::span<const std::byte> bytes_;
  format::FileHeader header_{};
  std::vector<format::SectionEntry> sections_;
  std::vector<AlignedBuffer> decoded_;  // per section; empty unless the section is compressed
  const void* manifest_ = nullptr;
  InputInfo input_;
  std::uint32_t positions_ = kNoSection, normals_ = kNoSection, triangles_ = kNoSection,
                triangle_mesh_ = kNoSection;
  // A 2D input's sections (blob_geo_input.cpp).
  struct GeoSections {
    std::uint32_t vertices = kNoSection, ring_vertices = kNoSection, polygon_rings = kNoSection,
                  feature_polygons = kNoSection, points = kNoSection, feature_points = kNoSection,
                  id_offsets = kNoSection, id_bytes = kNoSection, name_offsets = kNoSection,
                  name_bytes = kNoSection;
  } geo_;
  std::vector<StructureInfo> structures_;
};

}  // namespace kiln
