// Joining a mesh's vertices as Assimp 5.2.5's aiProcess_JoinIdenticalVertices did, for Kiln's own
// readers (PLY, STL): their output must match what the Assimp path gave, vertex for vertex.
#pragma once

#include <array>
#include <span>

#include "kiln/compiler/scene.hpp"

namespace kiln {

// Every triangle corner becomes the vertex Assimp kept for it: the newest earlier used vertex at
// the same position (bit for bit, -0 as +0) whose normal and texture coordinates are each within
// 1e-5 and whose colour is equal; else the corner keeps its own. Always a used vertex numbered
// lower or equal, so assemble_scene's dropping of unused vertices gives Assimp's numbering.
// `uvs` is empty or one pair per position (used only to decide joins).
void join_identical_vertices(ImportedMesh& mesh, std::span<const std::array<float, 2>> uvs = {});

}  // namespace kiln
