#pragma once

#include <cstdint>
#include <vector>

#include "kiln/compiler/build.hpp"

namespace kiln {

struct GeometrySectionIndices {
  std::uint32_t positions, triangles, triangle_mesh, normals;
};

struct BuiltBvh {
  std::string kind;
  const BvhBuildOptions* options;
  BvhStatistics stats;
  std::uint32_t nodes, triangles, prim_ids;  // section indices
};

// The manifest FlatBuffer for a scene. Deterministic: same scene and options, same bytes.
std::vector<std::byte> build_manifest(const Scene& scene, const BuildOptions& options,
                                      const GeometrySectionIndices& sections,
                                      const std::vector<BuiltBvh>& bvhs);

}  // namespace kiln
