#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "kiln/compiler/build.hpp"

namespace kiln {

struct GeometrySectionIndices {
  std::uint32_t positions, triangles, triangle_mesh, normals;
};

struct AccelEntry;

// The manifest FlatBuffer for a scene. Deterministic: same scene and options, same bytes.
std::vector<std::byte> build_manifest(const Scene& scene, const BuildOptions& options,
                                      const GeometrySectionIndices& sections,
                                      std::span<const AccelEntry> accels,
                                      std::span<const std::vector<std::uint32_t>> accel_sections);

}  // namespace kiln
