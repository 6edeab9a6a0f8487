// Assimp importer: node hierarchy walked in pre-order (children in file order), each node's
// meshes in its list order, faces in mesh order. Line primitives are discarded; a mesh of bare
// vertices alone is kept as a point cloud.
#include <assimp/DefaultIOSystem.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <assimp/Importer.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <optional>
#include <sstream>
#include <utility>

#include "import_obj.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/compiler/transform.hpp"
#include "rgba8.hpp"

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

// Assimp's default file access, recording what it opens and what it looks for in vain: an OBJ's
// .mtl and the parts of multi-file formats are only known to Assimp, and a depfile or the build
// cache must name them. (The importer owns this object and deletes it.)
class RecordingIOSystem final : public Assimp::DefaultIOSystem {
 public:
  explicit RecordingIOSystem(FileAccesses& accessed) : accessed_(accessed) {}
  bool Exists(const char* file) const override {
    const bool exists = DefaultIOSystem::Exists(file);
    if (!exists && file != nullptr && *file != '\0') accessed_.missing.emplace_back(file);
    return exists;
  }
  Assimp::IOStream* Open(const char* file, const char* mode) override {
    Assimp::IOStream* stream = DefaultIOSystem::Open(file, mode);
    if (file != nullptr && *file != '\0')
      (stream != nullptr ? accessed_.read : accessed_.missing).emplace_back(file);
    return stream;
  }

 private:
  FileAccesses& accessed_;
};

Matrix4 to_matrix4(const aiMatrix4x4& m) {
  // Assimp is row-major (a1..a4 is the first row); Matrix4 is column-major.
  return {m.a1, m.b1, m.c1, m.d1, m.a2, m.b2, m.c2, m.d2,
          m.a3, m.b3, m.c3, m.d3, m.a4, m.b4, m.c4, m.d4};
}

bool is_finite(const aiColor4D& c) {
  return std::isfinite(c.r) && std::isfinite(c.g) && std::isfinite(c.b) && std::isfinite(c.a);
}

// Whether `material` is `reference` under another name, property for property. Assimp 5.2.5's
// OBJ reader turns a `usemtl` naming a material no .mtl defines (box.obj's `usemtl Default`
// without a library) into such a copy of its DefaultMaterial: a grey the file never asked for.
bool is_renamed_copy(const aiMaterial& material, const aiMaterial& reference) {
  if (material.mNumProperties != reference.mNumProperties) return false;
  auto same = [](const aiMaterialProperty& a, const aiMaterialProperty& b) {
    return a.mKey == b.mKey && a.mSemantic == b.mSemantic && a.mIndex == b.mIndex &&
           a.mType == b.mType && a.mDataLength == b.mDataLength &&
           (a.mDataLength == 0 || std::memcmp(a.mData, b.mData, a.mDataLength) == 0);
  };
  for (unsigned p = 0; p < material.mNumProperties; ++p) {
    const aiMaterialProperty& mine = *material.mProperties[p];
    if (std::strcmp(mine.mKey.C_Str(), "?mat.name") == 0) continue;
    bool found = false;
    for (unsigned q = 0; q < reference.mNumProperties && !found; ++q)
      found = same(mine, *reference.mProperties[q]);
    if (!found) return false;
  }
  return true;
}

std::string material_name(const aiMaterial& material) {
  aiString name;
  if (material.Get(AI_MATKEY_NAME, name) != AI_SUCCESS) return {};
  return name.C_Str();
}

// The base colour of `material`, or none when the file gave none. Assimp invents a material
// for every mesh: "DefaultMaterial" (OBJ faces before any usemtl, STL, 3MF; an OBJ without .mtl
// uses only it), an unnamed one (PLY: white, OFF: grey) or, for OBJ, a renamed copy of
// DefaultMaterial (is_renamed_copy); none of these is a colour from the file.
std::optional<aiColor4D> material_color(const aiMaterial& material,
                                        const aiMaterial* default_material) {
  const std::string name = material_name(material);
  if (name.empty() || name == AI_DEFAULT_MATERIAL_NAME) return std::nullopt;
  if (default_material != nullptr && is_renamed_copy(material, *default_material))
    return std::nullopt;
  aiColor4D color;
  if (material.Get(AI_MATKEY_BASE_COLOR, color) != AI_SUCCESS &&
      material.Get(AI_MATKEY_COLOR_DIFFUSE, color) != AI_SUCCESS)
    return std::nullopt;
  return color;
}

// material_color for every material of the scene, by index (once per file, not per mesh).
std::vector<std::optional<aiColor4D>> material_colors(const aiScene& scene) {
  std::vector<std::optional<aiColor4D>> colors;
  if (scene.mMaterials == nullptr) return colors;
  const aiMaterial* default_material = nullptr;
  for (unsigned m = 0; m < scene.mNumMaterials; ++m)
    if (scene.mMaterials[m] != nullptr &&
        material_name(*scene.mMaterials[m]) == AI_DEFAULT_MATERIAL_NAME)
      default_material = scene.mMaterials[m];
  colors.resize(scene.mNumMaterials);
  for (unsigned m = 0; m < scene.mNumMaterials; ++m)
    if (scene.mMaterials[m] != nullptr)
      colors[m] = material_color(*scene.mMaterials[m], default_material);
  return colors;
}

// One colour per vertex: vertex colour set 0 times the base colour, or the base colour alone;
// empty when there is neither. A bad colour in a material no mesh uses is not an error.
std::vector<std::uint32_t> mesh_colors(const aiMesh& mesh, const std::optional<aiColor4D>& base,
                                       const std::string& path) {
  if (base && !is_finite(*base))
    throw ImportError(path + ": a material's base colour holds a non-finite value");
  const aiColor4D tint = base.value_or(aiColor4D(1, 1, 1, 1));
  std::vector<std::uint32_t> colors;
  if (mesh.HasVertexColors(0)) {
    colors.reserve(mesh.mNumVertices);
    for (unsigned v = 0; v < mesh.mNumVertices; ++v) {
      const aiColor4D& c = mesh.mColors[0][v];
      if (!is_finite(c)) throw ImportError(path + ": vertex colour holds a non-finite value");
      colors.push_back(pack_rgba8(double(c.r) * tint.r, double(c.g) * tint.g, double(c.b) * tint.b,
                                  double(c.a) * tint.a));
    }
  } else if (base) {
    colors.assign(mesh.mNumVertices, pack_rgba8(tint.r, tint.g, tint.b, tint.a));
  }
  return colors;
}

ImportedMesh convert_mesh(const aiMesh& mesh, const aiMatrix4x4& world,
                          const std::optional<aiColor4D>& base, const std::string& path) {
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
  out.colors = mesh_colors(mesh, base, path);
  out.triangles.reserve(mesh.mNumFaces);
  bool has_lines = false;
  for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
    const aiFace& face = mesh.mFaces[f];
    has_lines |= face.mNumIndices == 2;
    if (face.mNumIndices != 3 || face.mIndices == nullptr)
      continue;  // point and line primitives carry no surface
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
                                             const std::string& extension, bool bytes_are_file,
                                             const ImportLimits& limits, FileAccesses* accessed) {
  if (extension == ".ply" && is_ply_with_tristrips(bytes))
    throw ImportError(path +
                      ": PLY triangle strips are not supported (Assimp 5.2.5 misreads them)");
  if (extension == ".off") check_off_counts(path, bytes);
  if (extension == ".obj") check_obj_faces(path, bytes, limits.max_face_vertices);

  Assimp::Importer importer;
  // Reading from memory, Assimp still opens companions through this handler (its memory
  // handler wraps it).
  if (accessed != nullptr) importer.SetIOHandler(new RecordingIOSystem(*accessed));
  // No aiProcess_PreTransformVertices: it merges meshes by material and reorders triangles.
  // Read without post-processing, check the raw arrays ourselves, then triangulate: Assimp's
  // post-processing steps assert (abort) on inconsistent faces, and its own validation step
  // rejects a whole file for one empty mesh (an STL with an empty solid), as does SortByPType;
  // point and line primitives are skipped face by face in convert_mesh instead.
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

  const std::vector<std::optional<aiColor4D>> base_colors = material_colors(*scene);
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
      const std::optional<aiColor4D> base = mesh.mMaterialIndex < base_colors.size()
                                                ? base_colors[mesh.mMaterialIndex]
                                                : std::nullopt;
      meshes.push_back(convert_mesh(mesh, world, base, path));
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
