// glTF 2.0 importer (tinygltf, Draco primitives decoded through tinygltf's Draco support after
// draco_extension_check has vetted them). Scene order: the default scene (else scene 0) walked
// in pre-order from its root nodes in order; each node's mesh primitives in order. A file with
// no scenes contributes every mesh once, untransformed, in mesh order.
#include <tiny_gltf.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <optional>

#include "draco_extension_check.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/compiler/transform.hpp"
#include "rgba8.hpp"

namespace kiln {

namespace {

constexpr std::size_t kMaxNodeVisits = 1u << 24;
constexpr std::size_t kMaxNodeDepth = 1024;

Matrix4 local_transform(const tinygltf::Node& node) {
  if (node.matrix.size() == 16) {
    Matrix4 m;
    std::copy(node.matrix.begin(), node.matrix.end(), m.begin());
    return m;
  }
  Matrix4 m = kIdentity;
  if (node.scale.size() == 3) {
    Matrix4 s = kIdentity;
    s[0] = node.scale[0], s[5] = node.scale[1], s[10] = node.scale[2];
    m = s;
  }
  if (node.rotation.size() == 4) {
    const double x = node.rotation[0], y = node.rotation[1], z = node.rotation[2],
                 w = node.rotation[3];
    const Matrix4 r = {1 - 2 * (y * y + z * z),
                       2 * (x * y + z * w),
                       2 * (x * z - y * w),
                       0,
                       2 * (x * y - z * w),
                       1 - 2 * (x * x + z * z),
                       2 * (y * z + x * w),
                       0,
                       2 * (x * z + y * w),
                       2 * (y * z - x * w),
                       1 - 2 * (x * x + y * y),
                       0,
                       0,
                       0,
                       0,
                       1};
    m = multiply(r, m);
  }
  if (node.translation.size() == 3) {
    Matrix4 t = kIdentity;
    t[12] = node.translation[0], t[13] = node.translation[1], t[14] = node.translation[2];
    m = multiply(t, m);
  }
  return m;
}

struct AccessorView {
  const unsigned char* data = nullptr;
  std::size_t count = 0;
  std::size_t stride = 0;
  int component_type = 0;
  int components = 0;
};

// Every range a read below relies on is checked here, overflow-safe.
AccessorView view_accessor(const tinygltf::Model& model, int index, const std::string& path,
                           const std::string& what) {
  auto fail = [&](const std::string& reason) -> void {
    throw ImportError(path + ": " + what + " accessor " + std::to_string(index) + ": " + reason);
  };
  if (index < 0 || std::size_t(index) >= model.accessors.size()) fail("out of range");
  const tinygltf::Accessor& accessor = model.accessors[std::size_t(index)];
  if (accessor.sparse.isSparse) fail("sparse accessors are not supported");
  if (accessor.bufferView < 0 || std::size_t(accessor.bufferView) >= model.bufferViews.size())
    fail("has no valid bufferView");
  const tinygltf::BufferView& view = model.bufferViews[std::size_t(accessor.bufferView)];
  if (view.buffer < 0 || std::size_t(view.buffer) >= model.buffers.size())
    fail("buffer view names no valid buffer");
  const auto& buffer = model.buffers[std::size_t(view.buffer)].data;
  if (view.byteOffset > buffer.size() || view.byteLength > buffer.size() - view.byteOffset)
    fail("buffer view lies outside its buffer");
  const int component_size =
      tinygltf::GetComponentSizeInBytes(std::uint32_t(accessor.componentType));
  const int components = tinygltf::GetNumComponentsInType(std::uint32_t(accessor.type));
  if (component_size <= 0 || components <= 0) fail("invalid component type or type");
  const std::size_t element = std::size_t(component_size) * std::size_t(components);
  const std::size_t stride = view.byteStride != 0 ? view.byteStride : element;
  if (stride < element) fail("byteStride is smaller than an element");
  if (accessor.byteOffset > view.byteLength) fail("byteOffset lies outside its buffer view");
  const std::size_t available = view.byteLength - accessor.byteOffset;
  if (accessor.count > 0 &&
      (accessor.count - 1 > (std::numeric_limits<std::size_t>::max() - element) / stride ||
       (accessor.count - 1) * stride + element > available))
    fail(std::to_string(accessor.count) + " elements do not fit in the buffer view");
  return {buffer.data() + view.byteOffset + accessor.byteOffset, accessor.count, stride,
          accessor.componentType, components};
}

std::vector<format::Float3> read_vec3(const tinygltf::Model& model, int index,
                                      const std::string& path, const std::string& what) {
  const AccessorView view = view_accessor(model, index, path, what);
  if (view.component_type != TINYGLTF_COMPONENT_TYPE_FLOAT || view.components != 3)
    throw ImportError(path + ": " + what +
                      " must be float VEC3 (quantized attributes are not supported)");
  std::vector<format::Float3> values(view.count);
  for (std::size_t i = 0; i < view.count; ++i)
    std::memcpy(&values[i], view.data + i * view.stride, sizeof(format::Float3));
  return values;
}

using Rgba = std::array<double, 4>;

// The primitive's base colour: its material's baseColorFactor (tinygltf fills in the default
// [1,1,1,1]), or none when the primitive names no material.
std::optional<Rgba> base_color(const tinygltf::Model& model, const tinygltf::Primitive& primitive,
                               const std::string& path) {
  if (primitive.material < 0) return std::nullopt;
  if (std::size_t(primitive.material) >= model.materials.size())
    throw ImportError(path + ": primitive names material " + std::to_string(primitive.material) +
                      ", out of range");
  const auto& factor =
      model.materials[std::size_t(primitive.material)].pbrMetallicRoughness.baseColorFactor;
  if (factor.size() != 4)
    throw ImportError(path + ": baseColorFactor has " + std::to_string(factor.size()) +
                      " elements, not 4");
  Rgba color;
  for (int c = 0; c < 4; ++c) {
    if (!std::isfinite(factor[c]))
      throw ImportError(path + ": baseColorFactor holds a non-finite value");
    color[c] = factor[c];
  }
  return color;
}

// One component of a COLOR_0 element in [0, 1]. Integer colours are read as normalized whatever
// the accessor's flag says: the glTF spec allows them in no other form.
double color_component(const unsigned char* p, int component_type) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: {
      float v;
      std::memcpy(&v, p, 4);
      return v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return *p / 255.0;
    default: {  // TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, checked by read_colors
      std::uint16_t v;
      std::memcpy(&v, p, 2);
      return v / 65535.0;
    }
  }
}

// COLOR_0 times `tint`, packed: VEC3 (alpha 1) or VEC4, of float or normalized unsigned byte or
// short.
std::vector<std::uint32_t> read_colors(const tinygltf::Model& model, int index, const Rgba& tint,
                                       const std::string& path) {
  const AccessorView view = view_accessor(model, index, path, "COLOR_0");
  if (view.components != 3 && view.components != 4)
    throw ImportError(path + ": COLOR_0 must be VEC3 or VEC4");
  if (view.component_type != TINYGLTF_COMPONENT_TYPE_FLOAT &&
      view.component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
      view.component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT)
    throw ImportError(path + ": COLOR_0 must be float, unsigned byte or unsigned short");
  const std::size_t size = std::size_t(tinygltf::GetComponentSizeInBytes(view.component_type));
  std::vector<std::uint32_t> colors(view.count);
  for (std::size_t i = 0; i < view.count; ++i) {
    Rgba c = {1, 1, 1, 1};
    for (int k = 0; k < view.components; ++k) {
      c[k] = color_component(view.data + i * view.stride + k * size, view.component_type);
      if (!std::isfinite(c[k])) throw ImportError(path + ": COLOR_0 holds a non-finite value");
    }
    for (int k = 0; k < 4; ++k) c[k] *= tint[k];
    colors[i] = pack_rgba8(c[0], c[1], c[2], c[3]);
  }
  return colors;
}

std::vector<std::uint32_t> read_indices(const tinygltf::Model& model, int index,
                                        const std::string& path) {
  const AccessorView view = view_accessor(model, index, path, "indices");
  if (view.components != 1) throw ImportError(path + ": indices accessor is not SCALAR");
  std::vector<std::uint32_t> indices(view.count);
  for (std::size_t i = 0; i < view.count; ++i) {
    const unsigned char* p = view.data + i * view.stride;
    switch (view.component_type) {
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
        indices[i] = *p;
        break;
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
        std::uint16_t v;
        std::memcpy(&v, p, 2);
        indices[i] = v;
        break;
      }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
        std::memcpy(&indices[i], p, 4);
        break;
      default:
        throw ImportError(path + ": indices must be unsigned byte, short or int");
    }
  }
  return indices;
}

// Triangle list from a primitive's index sequence; strips alternate winding, fans pivot on 0.
std::vector<format::Triangle> assemble_triangles(const std::vector<std::uint32_t>& idx, int mode) {
  std::vector<format::Triangle> triangles;
  if (mode == TINYGLTF_MODE_TRIANGLES) {
    for (std::size_t i = 0; i + 2 < idx.size(); i += 3)
      triangles.push_back({idx[i], idx[i + 1], idx[i + 2]});
  } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
    for (std::size_t i = 0; i + 2 < idx.size(); ++i)
      triangles.push_back(i % 2 == 0 ? format::Triangle{idx[i], idx[i + 1], idx[i + 2]}
                                     : format::Triangle{idx[i + 1], idx[i], idx[i + 2]});
  } else if (mode == TINYGLTF_MODE_TRIANGLE_FAN) {
    for (std::size_t i = 1; i + 1 < idx.size(); ++i)
      triangles.push_back({idx[0], idx[i], idx[i + 1]});
  }
  return triangles;
}

void append_mesh(const tinygltf::Model& model, int mesh_index, const Matrix4& world,
                 const std::string& path, std::vector<ImportedMesh>& out) {
  if (mesh_index < 0 || std::size_t(mesh_index) >= model.meshes.size())
    throw ImportError(path + ": node names mesh " + std::to_string(mesh_index) + ", out of range");
  const tinygltf::Mesh& mesh = model.meshes[std::size_t(mesh_index)];
  for (std::size_t p = 0; p < mesh.primitives.size(); ++p) {
    const tinygltf::Primitive& primitive = mesh.primitives[p];
    const int mode = primitive.mode < 0 ? TINYGLTF_MODE_TRIANGLES : primitive.mode;
    if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
        mode != TINYGLTF_MODE_TRIANGLE_FAN)
      continue;  // point and line primitives carry no surface
    const auto position = primitive.attributes.find("POSITION");
    if (position == primitive.attributes.end()) continue;

    ImportedMesh part;
    part.name = mesh.name;
    if (mesh.primitives.size() > 1) {  // appended, not "/" + ...: GCC 12's -Wrestrict misfires
      part.name += '/';
      part.name += std::to_string(p);
    }
    part.transform = world;
    part.positions = read_vec3(model, position->second, path, "POSITION");
    if (const auto normal = primitive.attributes.find("NORMAL");
        normal != primitive.attributes.end()) {
      part.normals = read_vec3(model, normal->second, path, "NORMAL");
      if (part.normals.size() != part.positions.size())
        throw ImportError(path + ": NORMAL has " + std::to_string(part.normals.size()) +
                          " elements, POSITION " + std::to_string(part.positions.size()));
      for (const auto& n : part.normals)
        if (!std::isfinite(n.x) || !std::isfinite(n.y) || !std::isfinite(n.z) ||
            (n.x == 0 && n.y == 0 && n.z == 0))
          throw ImportError(path + ": NORMAL holds a zero-length or non-finite normal");
    }
    const std::optional<Rgba> base = base_color(model, primitive, path);
    if (const auto color = primitive.attributes.find("COLOR_0");
        color != primitive.attributes.end()) {
      part.colors = read_colors(model, color->second, base.value_or(Rgba{1, 1, 1, 1}), path);
      if (part.colors.size() != part.positions.size())
        throw ImportError(path + ": COLOR_0 has " + std::to_string(part.colors.size()) +
                          " elements, POSITION " + std::to_string(part.positions.size()));
    } else if (base) {
      part.colors.assign(part.positions.size(),
                         pack_rgba8((*base)[0], (*base)[1], (*base)[2], (*base)[3]));
    }
    std::vector<std::uint32_t> indices;
    if (primitive.indices >= 0) {
      indices = read_indices(model, primitive.indices, path);
      if (mode == TINYGLTF_MODE_TRIANGLES && indices.size() % 3 != 0)
        throw ImportError(path + ": index count " + std::to_string(indices.size()) +
                          " is not a multiple of 3");
      for (const auto i : indices)
        if (i >= part.positions.size())
          throw ImportError(path + ": index " + std::to_string(i) + " is out of range (" +
                            std::to_string(part.positions.size()) + " vertices)");
    } else {
      indices.resize(part.positions.size());
      for (std::size_t i = 0; i < indices.size(); ++i) indices[i] = std::uint32_t(i);
    }
    part.triangles = assemble_triangles(indices, mode);
    out.push_back(std::move(part));
  }
}

bool skip_image(tinygltf::Image*, const int, std::string*, std::string*, int, int,
                const unsigned char*, int, void*) {
  return true;  // geometry only: pixels are never decoded
}

// tinygltf's own file access, recording each buffer it reads and each place it looked in vain
// (it tries the file's folder, then the working directory). External images are never opened
// (TINYGLTF_NO_EXTERNAL_IMAGE), so only buffers come through here.
bool file_exists_recorded(const std::string& path, void* accessed) {
  const bool exists = tinygltf::FileExists(path, nullptr);
  if (!exists && !path.empty()) static_cast<FileAccesses*>(accessed)->missing.push_back(path);
  return exists;
}

bool read_whole_file_recorded(std::vector<unsigned char>* out, std::string* error,
                              const std::string& path, void* accessed) {
  // tinygltf sizes its read by seeking to the end: a directory (a URI of "../", found by
  // import_gltf_fuzzer) reports a size of 2^64 - 1 and the resize throws.
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    if (error != nullptr) *error += "buffer '" + path + "' is not a regular file\n";
    return false;
  }
  const bool ok = tinygltf::ReadWholeFile(out, error, path, nullptr);
  if (ok) static_cast<FileAccesses*>(accessed)->read.push_back(path);
  return ok;
}

}  // namespace

std::vector<ImportedMesh> import_gltf(const std::string& path, std::span<const std::byte> bytes,
                                      bool binary, FileAccesses* accessed) {
  const std::string base_dir = std::filesystem::path(path).parent_path().string();
  if (bytes.size() > std::numeric_limits<unsigned int>::max())
    throw ImportError(path + ": glTF files over 4 GiB are not supported");
  if (binary) {
    const GlbChunks chunks = split_glb(path, bytes);
    check_draco_extensions(path, chunks.json, chunks.bin, base_dir, accessed);
  } else {
    check_draco_extensions(path, {reinterpret_cast<const char*>(bytes.data()), bytes.size()}, {},
                           base_dir, accessed);
  }

  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(skip_image, nullptr);
  if (accessed != nullptr)
    loader.SetFsCallbacks({file_exists_recorded, tinygltf::ExpandFilePath, read_whole_file_recorded,
                           tinygltf::WriteWholeFile, accessed});
  tinygltf::Model model;
  std::string error, warning;
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  const auto size = static_cast<unsigned int>(bytes.size());
  const bool ok =
      binary ? loader.LoadBinaryFromMemory(&model, &error, &warning, data, size, base_dir)
             : loader.LoadASCIIFromString(&model, &error, &warning,
                                          reinterpret_cast<const char*>(data), size, base_dir);
  if (!ok) {
    if (error.empty()) error = "tinygltf failed without a reason";
    while (!error.empty() && (error.back() == '\n' || error.back() == ' ')) error.pop_back();
    for (auto& c : error)
      if (c == '\n') c = ';';
    throw ImportError(path + ": " + error);
  }

  std::vector<ImportedMesh> meshes;
  if (model.scenes.empty()) {
    for (std::size_t m = 0; m < model.meshes.size(); ++m)
      append_mesh(model, int(m), kIdentity, path, meshes);
    return meshes;
  }
  const std::size_t scene_index = model.defaultScene >= 0 ? std::size_t(model.defaultScene) : 0;
  if (scene_index >= model.scenes.size())
    throw ImportError(path + ": default scene is out of range");
  struct Pending {
    int node;
    Matrix4 parent;
    std::size_t depth;
  };
  std::vector<Pending> stack;
  const auto& roots = model.scenes[scene_index].nodes;
  for (auto it = roots.rbegin(); it != roots.rend(); ++it) stack.push_back({*it, kIdentity, 0});
  std::size_t visits = 0;
  while (!stack.empty()) {
    const Pending item = stack.back();
    stack.pop_back();
    if (item.node < 0 || std::size_t(item.node) >= model.nodes.size())
      throw ImportError(path + ": node " + std::to_string(item.node) + " is out of range");
    if (++visits > kMaxNodeVisits || item.depth > kMaxNodeDepth)
      throw ImportError(path + ": node hierarchy has a cycle or is absurdly deep");
    const tinygltf::Node& node = model.nodes[std::size_t(item.node)];
    const Matrix4 world = multiply(item.parent, local_transform(node));
    if (node.mesh >= 0) append_mesh(model, node.mesh, world, path, meshes);
    for (auto it = node.children.rbegin(); it != node.children.rend(); ++it)
      stack.push_back({*it, world, item.depth + 1});
  }
  return meshes;
}

}  // namespace kiln
