// The manifest (section 0): the input's table, the sources, and one Structure per structure.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "kiln/compiler/advise.hpp"
#include "kiln/compiler/build.hpp"
#include "kiln/runtime/blob.hpp"

namespace kiln {

/// Where compile_blob put the input's sections; kNoSection where the input has none.
struct InputSectionIndices {
  std::uint32_t positions = kNoSection, triangles = kNoSection, triangle_mesh = kNoSection,
                normals = kNoSection;
  // An event table's (issue 18; event_table_sections.cpp).
  std::uint32_t event_points = kNoSection, event_times = kNoSection, event_codes = kNoSection,
                event_label_offsets = kNoSection, event_label_bytes = kNoSection;
  // The 2D inputs (geo_input.cpp): a polygon layer's or a point table's arrays.
  std::uint32_t vertices = kNoSection, ring_vertices = kNoSection, polygon_rings = kNoSection,
                feature_polygons = kNoSection, points = kNoSection, feature_points = kNoSection,
                id_offsets = kNoSection, id_bytes = kNoSection, name_offsets = kNoSection,
                name_bytes = kNoSection;
};

/// The manifest FlatBuffer for a scene. `built[i]` is the structure `options.structures[i]` asked
/// for, and `sections[i]` the blob's indices of its sections; `advice`, what each `--accel auto`
/// chose (its untimed columns only). Deterministic: same scene and options, same bytes.
std::vector<std::byte> build_manifest(const Scene& scene, const BuildOptions& options,
                                      const InputSectionIndices& input,
                                      std::span<const BuiltStructure> built,
                                      std::span<const std::vector<std::uint32_t>> sections,
                                      std::span<const AutoChoice> advice = {});

}  // namespace kiln
