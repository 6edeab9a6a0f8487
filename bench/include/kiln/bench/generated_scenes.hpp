// Procedural scenes that show when each ray structure wins, as plain triangle meshes: a pure
// function of their arguments (the same floats on every machine: SplitMix64 and explicit
// conversions, no std distributions). kiln_make_scene writes them as PLY; tests build them in
// memory at small sizes.
#pragma once

#include <cstdint>
#include <vector>

#include "kiln/formats/geometry.hpp"

namespace kiln::bench {

struct GeneratedMesh {
  std::vector<format::Float3> positions;
  std::vector<format::Triangle> triangles;
};

/// `count` small triangles scattered uniformly in the unit cube, each with its own three
/// vertices and a random orientation, edges about half the mean spacing: the case uniform grids
/// are made for (every cell holds about as many triangles).
GeneratedMesh uniform_triangles(std::uint64_t count, std::uint64_t seed);

/// The "teapot in a stadium": a finely tessellated sphere of radius 1 at the origin holding
/// about 98% of `count` triangles, inside a stadium of big triangles (a ground disc, a
/// terraced bowl and a wall, radius 400) holding the rest (at least 256). A uniform grid sized
/// by the triangle count puts the whole sphere in a cell or two.
GeneratedMesh teapot_in_stadium(std::uint64_t count, std::uint64_t seed);

}  // namespace kiln::bench
