// The runtime's registry of structure kinds: for each kind, the sections it owns, what it
// consumes, how to open a validated view of it from a blob, its deep check and its description.
// Tools loop over it; they never name a structure. docs/ARCHITECTURE.md says how to add a kind.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string_view>

#include "kiln/runtime/capabilities.hpp"
#include "kiln/runtime/description.hpp"
#include "kiln/runtime/input_kind.hpp"

namespace kiln {

class Blob;
struct StructureInfo;

/// One structure kind, as the runtime knows it. Every function throws BlobError (one line
/// naming the blob, the structure and what is wrong) on bad bytes.
struct StructureKind {
  std::string_view name;                    ///< the kind name, as `kiln build --accel` takes it
  std::string_view summary;                 ///< one line: what it is, what it answers
  InputKind consumes;                       ///< what it is built over
  std::span<const std::uint32_t> sections;  ///< the section kinds (FourCC) it may own
  std::uint8_t desc_type;                   ///< its member of the manifest's StructureDesc
  /// O(1) checks of its manifest entry: section indices, kinds, element sizes and counts.
  /// Blob::open runs it for every structure.
  void (*check)(const Blob& blob, const StructureInfo& info);
  /// A validated view (O(structure) walk at most: no O(bytes) checksum).
  std::unique_ptr<StructureView> (*open)(const Blob& blob, const StructureInfo& info);
  /// The deep check behind Blob::verify (and `kiln verify`), beyond open's walk.
  void (*verify)(const Blob& blob, const StructureInfo& info);
  /// Parameters and statistics for `kiln dump`.
  Description (*describe)(const Blob& blob, const StructureInfo& info);
};

/// Every registered kind, in registration order.
std::span<const StructureKind* const> structure_kinds();
/// The kind named `name`, or nullptr.
const StructureKind* find_structure_kind(std::string_view name);

/// Opens the structure named `name` of `blob` through its kind. Throws BlobError when the blob
/// has no such structure.
std::unique_ptr<StructureView> open_structure(const Blob& blob, std::string_view name);

}  // namespace kiln
