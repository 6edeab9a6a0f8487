// The compiler's registry of structure kinds: each kind's options (with defaults, validation
// and the global flag that may set them), what it consumes, and its builder. `kiln build` and
// the build cache loop over it; they never name a structure. docs/ARCHITECTURE.md says how to
// add a kind.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "kiln/compiler/blob_writer.hpp"
#include "kiln/compiler/scene.hpp"
#include "kiln/runtime/input_kind.hpp"

namespace flatbuffers {
class FlatBufferBuilder;  // declared only: the schema stays private to the compiler
}

namespace kiln {

/// One option of a structure kind, set per structure as `--accel KIND:key=value,...` or for
/// every structure of the kind by its global flag (`--resolution 256`).
struct StructureOption {
  std::string key;            ///< "resolution"
  std::string flag;           ///< "--resolution", or empty; flags may be shared between kinds
  std::string default_value;  ///< canonical text; "false" for a switch
  std::string help;
  bool is_switch = false;  ///< boolean: the global flag takes no value
  /// Checks a value and returns its canonical text; throws std::invalid_argument with a
  /// one-line reason (the caller adds which option).
  std::function<std::string(std::string_view)> parse;
  bool enters_output = true;  ///< false: never changes the blob (not in the cache key)
};

/// A structure to build, resolved: every option of its kind present, canonical.
struct StructureRequest {
  std::string name;  ///< unique in the blob; the kind's name by default
  std::string kind;
  std::map<std::string, std::string> options;

  std::uint32_t uint_option(const std::string& key) const;
  float float_option(const std::string& key) const;
  double double_option(const std::string& key) const;
  bool switch_option(const std::string& key) const;
  const std::string& text_option(const std::string& key) const;
};

/// What one structure contributes to a blob: its sections (borrowing from `storage`), its
/// StructureDesc member for the manifest, and a line for `kiln build --stats`.
struct BuiltStructure {
  std::vector<SectionPayload> sections;
  std::shared_ptr<const void> storage;
  /// Writes the kind's description table given the blob's indices of `sections` (same order);
  /// returns the StructureDesc union type and the table's offset.
  std::function<std::pair<std::uint8_t, std::uint32_t>(flatbuffers::FlatBufferBuilder&,
                                                       std::span<const std::uint32_t>)>
      describe;
  std::string summary;  ///< statistics, one line, no timing
};

/// A structure kind as the compiler sees it; each kind's `<kind>_entry.cpp` defines one and
/// compiler/src/structure_registry.cpp lists it.
struct StructureBuilder {
  std::string kind;                      ///< the name `--accel` takes and the manifest records
  std::string help;                      ///< one line for `kiln build --help`
  InputKind consumes;                    ///< compile_blob refuses an input that does not provide it
  std::vector<StructureOption> options;  ///< in help and cache-key order
  /// Builds from a request resolved for this kind; `threads` never changes the result.
  BuiltStructure (*build)(const Scene& scene, const StructureRequest& request, unsigned threads);
  /// `kiln advise` (advise.hpp) tries every triangle kind with its default options, then these
  /// `--accel` specs of the same kind worth comparing (e.g. another width).
  std::vector<std::string> advise_variants{};
  /// Hits only approximate the surface (voxels): advise and `--accel auto` skip the kind.
  bool advise_skip = false;
};

/// Every registered kind, in registration order (the first triangle kind is the default ray
/// structure of tools that need one).
std::span<const StructureBuilder* const> structure_builders();
const StructureBuilder* find_structure_builder(std::string_view kind);

/// Resolves "KIND[:key=value,...]" (key `name` names the structure): each option from the spec,
/// else from `flags` (global flag -> value, as given on the command line), else its default.
/// Throws std::invalid_argument with one line for an unknown kind or key or a bad value.
StructureRequest resolve_structure_request(std::string_view spec,
                                           const std::map<std::string, std::string>& flags);

/// Option parsers for StructureOption::parse.
std::function<std::string(std::string_view)> parse_uint_in(std::uint64_t lo, std::uint64_t hi);
std::function<std::string(std::string_view)> parse_float_in(double lo, double hi);
std::function<std::string(std::string_view)> parse_one_of(std::vector<std::string> choices);
std::function<std::string(std::string_view)> parse_switch();

}  // namespace kiln
