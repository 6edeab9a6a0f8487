// `kiln build` as a library: import inputs, assemble the scene, write the blob.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "kiln/compiler/blob_writer.hpp"
#include "kiln/compiler/event_table.hpp"
#include "kiln/compiler/geo_import.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/compiler/scene.hpp"
#include "kiln/compiler/structure_builder.hpp"

namespace kiln {

inline constexpr const char* kToolName = "kiln";
extern const char* const kToolVersion;

/// What building one structure produced, for `kiln build --stats` (never stored: timing would
/// break determinism).
struct AccelReport {
  std::string name;     ///< the structure's name in the blob
  std::string kind;     ///< its kind (structure_builders())
  std::string summary;  ///< its statistics in one line
  double build_seconds = 0;
};

struct BuildOptions {
  std::vector<std::string> inputs;
  /// The structures to build, in blob order (resolve_structure_request); names unique.
  std::vector<StructureRequest> structures;
  CompressionOptions compression;
  unsigned threads = 0;  // 0 = all hardware threads; never affects the output
  ImportLimits limits;   // refuse hostile inputs early; never affects an output that is written
  EventColumns events;   // issue 18: --lat/--lon/--time/--category make the CSV an event table
  GeoImportOptions geo;  // how a 2D input (GeoJSON, CSV) is read; enters the cache key
};

/// The kind of input a scene is: a 3D point set when it has no triangle, else a triangle scene.
InputKind input_kind_of(const Scene& scene);

// (stage, done, total): called from the calling thread only.
using BuildProgress = std::function<void(std::string_view, std::uint64_t, std::uint64_t)>;

// Imports every input (in parallel, one task per file) and flattens them in input order; the
// scene's `accessed` lists every file the import read. Throws ImportError naming the first
// failing input in command-line order, or when nothing is left: no triangle and no vertex.
// A 2D input (is_geo_input_name: GeoJSON, CSV) is read with `geo` into `scene.polygons` or
// `scene.points2`; it must be the blob's only input. With `events` active (issue 18), the one
// input is read as an event table instead.
Scene import_scene(const std::vector<std::string>& inputs, unsigned threads,
                   const BuildProgress& progress = {}, const ImportLimits& limits = {},
                   const GeoImportOptions& geo = {}, const EventColumns& events = {});

/// A compiled blob as pieces (BlobPieces) with what they borrow: each structure's sections and
/// the manifest. The input's sections borrow the scene, which must outlive it.
struct CompiledBlob {
  std::vector<BuiltStructure> structures;
  std::vector<std::byte> manifest;
  BlobPieces pieces;
};

// The complete blob for a scene: manifest (section 0), then the input's sections, then each
// structure's. Throws ImportError when a structure consumes what the scene's input kind does not
// provide (triangles of a point set), when a point set is asked for no structure, or when two
// structures share a name. `compile_blob_pieces` keeps it in pieces for writing straight to a
// file; `compile_blob` concatenates them.
CompiledBlob compile_blob_pieces(const Scene& scene, const BuildOptions& options,
                                 std::vector<AccelReport>* reports = nullptr);
std::vector<std::byte> compile_blob(const Scene& scene, const BuildOptions& options,
                                    std::vector<AccelReport>* reports = nullptr);

}  // namespace kiln
