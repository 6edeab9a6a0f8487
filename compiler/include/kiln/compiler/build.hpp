// `kiln build` as a library: import inputs, assemble the scene, write the blob.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "kiln/compiler/blob_writer.hpp"
#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/compiler/esvo_builder.hpp"
#include "kiln/compiler/kdtree_builder.hpp"
#include "kiln/compiler/point_tree_builder.hpp"
#include "kiln/compiler/scene.hpp"
#include "kiln/compiler/voxelizer.hpp"

namespace kiln {

inline constexpr const char* kToolName = "kiln";
extern const char* const kToolVersion;

// One acceleration structure to build: kind "bvh" (binned or sweep builder), "sbvh", "kdtree",
// "points", "dag" or "esvo"; only the options of its kind are read.
struct AccelRequest {
  std::string kind;
  BvhBuildOptions bvh;
  KdTreeBuildOptions kdtree;
  PointTreeBuildOptions points{};
  VoxelizeOptions voxels{};  // "dag"
  EsvoBuildOptions esvo{};
};

// Whether a structure of this kind is built over triangles (every kind but "points").
bool needs_triangles(const std::string& kind);

// What building one structure produced, for `kiln build --stats` (never stored: timing would
// break determinism).
struct AccelReport {
  std::string kind;
  std::string summary;  // its statistics in one line
  double build_seconds = 0;
};

struct BuildOptions {
  std::vector<std::string> inputs;
  std::vector<AccelRequest> accels;
  CompressionOptions compression;
  unsigned threads = 0;  // 0 = all hardware threads; never affects the output
};

// (stage, done, total): called from the calling thread only.
using BuildProgress = std::function<void(std::string_view, std::uint64_t, std::uint64_t)>;

// Imports every input (in parallel, one task per file) and flattens them in input order; the
// scene's `accessed` lists every file the import read. Throws ImportError naming the first
// failing input in command-line order, or when nothing is left: no triangle and no point.
Scene import_scene(const std::vector<std::string>& inputs, unsigned threads,
                   const BuildProgress& progress = {});

// The complete blob for a scene: manifest (section 0), then the geometry sections, then each
// structure's. Throws ImportError when a triangle structure is asked of a scene with no triangles
// (a point cloud), or when such a scene is asked for nothing.
std::vector<std::byte> compile_blob(const Scene& scene, const BuildOptions& options,
                                    std::vector<AccelReport>* reports = nullptr);

}  // namespace kiln
