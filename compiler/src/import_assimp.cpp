// Assimp importer: node hierarchy walked in pre-order (children in file order), each node's
// meshes in its list order, faces in mesh order. Point and line primitives are discarded.
#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <cmath>
#include <cstring>
#include <utility>

#include "kiln/compiler/import.hpp"
#include "kiln/compiler/transform.hpp"

namespace kiln {

namespace {

// Assimp 5.2.5 reads PLY triangle strips as one triangle without a word; refuse instead.
bool is_ply_with_tristrips(std::span<const std::byte> bytes) {
  const std::size_t head = std::min<std::size_t>(bytes.size(), 4096);
  const std::string header(reinterpret_cast<const char*>(bytes.data()), head);
  const auto end = header.find("end_header");
  return header.find("element tristrips") < end;
}

Matrix4 to_matrix4(const aiMatrix4x4& m) {
  // Assimp is row-major (a1..a4 is the first row); Matrix4 is column-major.
  return {m.a1, m.b1, m.c1, m.d1, m.a2, m.b2, m.c2, m.d2,
          m.a3, m.b3, m.c3, m.d3, m.a4, m.b4, m.c4, m.d4};
}

ImportedMesh convert_mesh(const aiMesh& mesh, const aiMatrix4x4& world, const std::string& path) {
  ImportedMesh out;
  out.name = mesh.mName.length > 0 ? std::string(mesh.mName.C_Str()) : std::string();
  out.transform = to_matrix4(world);
  out.positions.reserve(mesh.mNumVertices);
  for (unsigned v = 0; v < mesh.mNumVertices; ++v)
    out.positions.push_back({mesh.mVertices[v].x, mesh.mVertices[v].y, mesh.mVertices[v].z});
  if (mesh.HasNormals()) {
    out.normals.reserve(mesh.mNumVertices);
    for (unsigned v = 0; v < mesh.mNumVertices; ++v)
      out.normals.push_back({mesh.mNormals[v].x, mesh.mNormals[v].y, mesh.mNormals[v].z});
  }
  out.triangles.reserve(mesh.mNumFaces);
  for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
    const aiFace& face = mesh.mFaces[f];
    if (face.mNumIndices != 3) continue;  // points and lines carry no surface
    format::Triangle t{};
    for (int i = 0; i < 3; ++i) {
      if (face.mIndices[i] >= mesh.mNumVertices)
        throw ImportError(path + ": face " + std::to_string(f) + " names vertex " +
                          std::to_string(face.mIndices[i]) + " of " +
                          std::to_string(mesh.mNumVertices));
      t.v[i] = face.mIndices[i];
    }
    out.triangles.push_back(t);
  }
  return out;
}

}  // namespace

std::vector<ImportedMesh> import_with_assimp(const std::string& path, std::span<const std::byte> bytes,
                                             const std::string& extension, bool bytes_are_file) {
  if (extension == ".ply" && is_ply_with_tristrips(bytes))
    throw ImportError(path + ": PLY triangle strips are not supported (Assimp 5.2.5 misreads them)");

  Assimp::Importer importer;
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  // No aiProcess_PreTransformVertices: it merges meshes by material and reorders triangles.
  const unsigned flags = aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                         aiProcess_SortByPType | aiProcess_ValidateDataStructure;
  // Reading from the path lets Assimp find companion files; inflated bytes have no path.
  const aiScene* scene =
      bytes_are_file ? importer.ReadFile(path, flags)
                     : importer.ReadFileFromMemory(bytes.data(), bytes.size(), flags,
                                                   extension.empty() ? "" : extension.c_str() + 1);
  if (scene == nullptr) {
    std::string reason = importer.GetErrorString();
    if (reason.empty()) reason = "unknown Assimp error";
    if (const auto newline = reason.find('\n'); newline != std::string::npos) reason.resize(newline);
    throw ImportError(path + ": " + reason);
  }
  if ((scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE) != 0 || scene->mRootNode == nullptr)
    throw ImportError(path + ": Assimp produced an incomplete scene");

  std::vector<ImportedMesh> meshes;
  // Explicit stack: a hostile file's deep hierarchy must not overflow the call stack.
  std::vector<std::pair<const aiNode*, aiMatrix4x4>> stack{{scene->mRootNode, aiMatrix4x4()}};
  while (!stack.empty()) {
    auto [node, parent] = stack.back();
    stack.pop_back();
    const aiMatrix4x4 world = parent * node->mTransformation;
    for (unsigned i = 0; i < node->mNumMeshes; ++i) {
      if (node->mMeshes[i] >= scene->mNumMeshes)
        throw ImportError(path + ": node references a missing mesh");
      const aiMesh& mesh = *scene->mMeshes[node->mMeshes[i]];
      if ((mesh.mPrimitiveTypes & aiPrimitiveType_TRIANGLE) == 0) continue;
      meshes.push_back(convert_mesh(mesh, world, path));
      if (meshes.back().name.empty()) meshes.back().name = node->mName.C_Str();
    }
    for (unsigned c = node->mNumChildren; c-- > 0;) stack.emplace_back(node->mChildren[c], world);
  }
  return meshes;
}

}  // namespace kiln
