#pragma once

#include <cstdint>
#include <vector>

#include "kiln/compiler/build.hpp"

namespace kiln {

struct GeometrySectionIndices {
  std::uint32_t positions, triangles, triangle_mesh, normals;
};

// The manifest FlatBuffer for a scene. Deterministic: same scene and options, same bytes.
std::vector<std::byte> build_manifest(const Scene& scene, const BuildOptions& options,
                                      const GeometrySectionIndices& sections);

}  // namespace kiln
