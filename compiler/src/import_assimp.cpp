// Assimp importer: node hierarchy walked in pre-order (children in file order), each node's
// meshes in its list order, faces in mesh order. Line primitives are discarded; a mesh of points
// alone is kept as a point cloud.
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <assimp/Importer.hpp>

#include <cmath>
#include <cstring>
#include <sstream>
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

// Assimp 5.2.5 believes an OFF header's counts and spends tens of seconds (or aborts under
// ASan) reserving memory for 10^11 vertices. Each text vertex needs at least 6 bytes ("0 0 0\n")
// and each face 2, so counts the file cannot hold are refused up front.
void check_off_counts(const std::string& path, std::span<const std::byte> bytes) {
  const std::string head(reinterpret_cast<const char*>(bytes.data()),
                         std::min<std::size_t>(bytes.size(), 4096));
  std::istringstream in(head);
  std::string token;
  in >> token;
  if (token.empty() || token.find("OFF") == std::string::npos ||
      token.find("OFF") + 3 != token.size())
    return;  // binary or unusual: Assimp's problem
  for (char c = char(in.peek()); in && (c == ' ' || c == '\n' || c == '\r' || c == '#');
       c = char(in.peek())) {
    if (c == '#')
      std::getline(in, token);
    else
      in.get();
  }
  unsigned long long vertices = 0, faces = 0;
  if (!(in >> vertices >> faces)) return;
  if (vertices > bytes.size() / 6 || faces > bytes.size() / 2 ||
      vertices * 6 + faces * 2 > bytes.size())
    throw ImportError(path + ": OFF header claims " + std::to_string(vertices) + " vertices and " +
                      std::to_string(faces) + " faces, more than its " +
                      std::to_string(bytes.size()) + " bytes can hold");
}

Matrix4 to_matrix4(const aiMatrix4x4& m) {
  // Assimp is row-major (a1..a4 is the first row); Matrix4 is column-major.
  return {m.a1, m.b1, m.c1, m.d1, m.a2, m.b2, m.c2, m.d2,
          m.a3, m.b3, m.c3, m.d3, m.a4, m.b4, m.c4, m.d4};
}

ImportedMesh convert_mesh(const aiMesh& mesh, const aiMatrix4x4& world, const std::string& path) {
  ImportedMesh out;
  if (mesh.mNumVertices == 0) return out;
  if (mesh.mVertices == nullptr || (mesh.mNumFaces > 0 && mesh.mFaces == nullptr))
    throw ImportError(path + ": Assimp returned a mesh without vertex or face arrays");
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
  bool has_lines = false;
  for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
    const aiFace& face = mesh.mFaces[f];
    has_lines |= face.mNumIndices == 2;
    if (face.mNumIndices != 3 || face.mIndices == nullptr)
      continue;  // points and lines carry no surface
    // Index ranges are checked once for every importer, in import_file.
    const format::Triangle t{{face.mIndices[0], face.mIndices[1], face.mIndices[2]}};
    out.triangles.push_back(t);
  }
  // Vertices without faces, or with point faces only, are a point cloud (a PLY scan, an OBJ of
  // `v` lines); a wireframe of lines is neither surface nor cloud and stays dropped.
  out.point_cloud = out.triangles.empty() && !has_lines;
  return out;
}

void check_raw_scene(const aiScene& scene, const std::string& path) {
  if (scene.mNumMeshes > 0 && scene.mMeshes == nullptr)
    throw ImportError(path + ": mesh array missing");
  for (unsigned m = 0; m < scene.mNumMeshes; ++m) {
    const aiMesh* mesh = scene.mMeshes[m];
    if (mesh == nullptr) throw ImportError(path + ": mesh " + std::to_string(m) + " is missing");
    if ((mesh->mNumVertices > 0 && mesh->mVertices == nullptr) ||
        (mesh->mNumFaces > 0 && mesh->mFaces == nullptr))
      throw ImportError(path + ": mesh " + std::to_string(m) + " lacks its vertex or face array");
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices == 0 || face.mIndices == nullptr)
        throw ImportError(path + ": face " + std::to_string(f) + " has no vertices");
      for (unsigned i = 0; i < face.mNumIndices; ++i)
        if (face.mIndices[i] >= mesh->mNumVertices)
          throw ImportError(path + ": face " + std::to_string(f) + " names vertex " +
                            std::to_string(face.mIndices[i]) + " of " +
                            std::to_string(mesh->mNumVertices));
    }
  }
}

}  // namespace

std::vector<ImportedMesh> import_with_assimp(const std::string& path,
                                             std::span<const std::byte> bytes,
                                             const std::string& extension, bool bytes_are_file) {
  if (extension == ".ply" && is_ply_with_tristrips(bytes))
    throw ImportError(path +
                      ": PLY triangle strips are not supported (Assimp 5.2.5 misreads them)");
  if (extension == ".off") check_off_counts(path, bytes);

  Assimp::Importer importer;
  // No aiProcess_PreTransformVertices: it merges meshes by material and reorders triangles.
  // Read without post-processing, check the raw arrays ourselves, then triangulate: Assimp's
  // post-processing steps assert (abort) on inconsistent faces, and its own validation step
  // rejects a whole file for one empty mesh (an STL with an empty solid), as does SortByPType;
  // points and lines are skipped face by face in convert_mesh instead.
  // Reading from the path lets Assimp find companion files; inflated bytes have no path.
  const aiScene* scene =
      bytes_are_file ? importer.ReadFile(path, 0)
                     : importer.ReadFileFromMemory(bytes.data(), bytes.size(), 0,
                                                   extension.empty() ? "" : extension.c_str() + 1);
  if (scene != nullptr) {
    check_raw_scene(*scene, path);
    scene = importer.ApplyPostProcessing(aiProcess_Triangulate | aiProcess_JoinIdenticalVertices);
  }
  if (scene == nullptr) {
    std::string reason = importer.GetErrorString();
    if (reason.empty()) reason = "unknown Assimp error";
    if (const auto newline = reason.find('\n'); newline != std::string::npos)
      reason.resize(newline);
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
      if (scene->mMeshes == nullptr || scene->mMeshes[node->mMeshes[i]] == nullptr)
        throw ImportError(path + ": node references a missing mesh");
      const aiMesh& mesh = *scene->mMeshes[node->mMeshes[i]];
      meshes.push_back(convert_mesh(mesh, world, path));
      if (meshes.back().triangles.empty() && !meshes.back().point_cloud) {
        meshes.pop_back();
        continue;
      }
      if (meshes.back().name.empty()) meshes.back().name = node->mName.C_Str();
    }
    for (unsigned c = node->mNumChildren; c-- > 0;)
      if (node->mChildren[c] != nullptr) stack.emplace_back(node->mChildren[c], world);
  }
  return meshes;
}

}  // namespace kiln
