// The 2D inputs (a polygon layer, a point table) as blob sections and manifest tables.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <utility>

#include "kiln/compiler/scene.hpp"
#include "manifest_builder.hpp"

namespace flatbuffers {
class FlatBufferBuilder;
}

namespace kiln {

/// Adds one required section (kind, element size, count, bytes) and returns its index.
using AddSection = std::function<std::uint32_t(std::uint32_t, std::uint32_t, std::uint64_t,
                                               std::span<const std::byte>)>;

/// Appends the sections of the scene's 2D input (none when it has none).
void add_geo_input_sections(const Scene& scene, InputSectionIndices& indices,
                            const AddSection& add);

/// The manifest's Input member for the scene's 2D input: (union type, table offset).
std::pair<std::uint8_t, std::uint32_t> geo_input_table(flatbuffers::FlatBufferBuilder& fbb,
                                                       const Scene& scene,
                                                       const InputSectionIndices& indices);

}  // namespace kiln
