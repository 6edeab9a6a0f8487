// Raw Draco bitstreams (.drc), decoded with Draco itself (Assimp cannot read them).
#include <draco/compression/decode.h>

#include "import_draco_mesh.hpp"
#include "kiln/compiler/import.hpp"

namespace kiln {

ImportedMesh convert_draco_mesh(const draco::Mesh& mesh, const std::string& path) {
  const draco::PointAttribute* position =
      mesh.GetNamedAttribute(draco::GeometryAttribute::POSITION);
  if (position == nullptr || position->num_components() != 3)
    throw ImportError(path + ": Draco mesh has no 3-component POSITION attribute");
  const draco::PointAttribute* normal = mesh.GetNamedAttribute(draco::GeometryAttribute::NORMAL);
  if (normal != nullptr && normal->num_components() != 3) normal = nullptr;

  ImportedMesh out;
  const auto point_count = mesh.num_points();
  out.positions.resize(point_count);
  if (normal != nullptr) out.normals.resize(point_count);
  for (draco::PointIndex p(0); p < point_count; ++p) {
    float value[3];
    if (!position->ConvertValue<float, 3>(position->mapped_index(p), value))
      throw ImportError(path + ": Draco POSITION cannot be read as float");
    out.positions[p.value()] = {value[0], value[1], value[2]};
    if (normal != nullptr) {
      if (!normal->ConvertValue<float, 3>(normal->mapped_index(p), value))
        throw ImportError(path + ": Draco NORMAL cannot be read as float");
      out.normals[p.value()] = {value[0], value[1], value[2]};
    }
  }
  out.triangles.resize(mesh.num_faces());
  for (draco::FaceIndex f(0); f < mesh.num_faces(); ++f) {
    const auto& face = mesh.face(f);
    for (int i = 0; i < 3; ++i) out.triangles[f.value()].v[i] = face[i].value();
  }
  return out;
}

std::vector<ImportedMesh> import_draco(const std::string& path, std::span<const std::byte> bytes) {
  draco::DecoderBuffer buffer;
  buffer.Init(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  const auto type = draco::Decoder::GetEncodedGeometryType(&buffer);
  if (!type.ok())
    throw ImportError(path + ": not a Draco bitstream: " + type.status().error_msg_string());
  if (type.value() != draco::TRIANGULAR_MESH)
    throw ImportError(path + ": Draco point cloud has no triangles");
  draco::Decoder decoder;
  auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
  if (!decoded.ok()) throw ImportError(path + ": Draco: " + decoded.status().error_msg_string());
  std::vector<ImportedMesh> meshes;
  meshes.push_back(convert_draco_mesh(*decoded.value(), path));
  meshes.back().name = "draco";
  return meshes;
}

}  // namespace kiln
