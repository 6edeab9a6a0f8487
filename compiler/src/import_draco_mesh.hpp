#pragma once

#include <draco/mesh/mesh.h>

#include <string>

#include "kiln/compiler/scene.hpp"

namespace kiln {

// A decoded Draco mesh as an ImportedMesh (no transform applied). Throws ImportError.
ImportedMesh convert_draco_mesh(const draco::Mesh& mesh, const std::string& path);

}  // namespace kiln
