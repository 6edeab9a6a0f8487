// Raw Draco bitstreams (.drc), decoded with Draco itself (Assimp cannot read them).
#include <draco/compression/decode.h>

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "draco_counts_check.hpp"
#include "import_draco_mesh.hpp"
#include "kiln/compiler/import.hpp"
#include "rgba8.hpp"

namespace kiln {

namespace {

// One COLOR value (3 components, alpha 1, or 4) in [0, 1]. Unsigned integers are read raw and
// scaled here: a colour only means anything normalized, whatever the attribute's flag says
// (ConvertValue<float> would honour the flag and return 0..255 without it).
bool read_color(const draco::PointAttribute& color, draco::AttributeValueIndex index,
                double (&out)[4]) {
  const int n = color.num_components();
  out[3] = 1;
  switch (color.data_type()) {
    case draco::DT_UINT8: {
      std::uint8_t v[4];
      if (!color.ConvertValue<std::uint8_t>(index, std::int8_t(n), v)) return false;
      for (int c = 0; c < n; ++c) out[c] = v[c] / 255.0;
      return true;
    }
    case draco::DT_UINT16: {
      std::uint16_t v[4];
      if (!color.ConvertValue<std::uint16_t>(index, std::int8_t(n), v)) return false;
      for (int c = 0; c < n; ++c) out[c] = v[c] / 65535.0;
      return true;
    }
    case draco::DT_FLOAT32:
    case draco::DT_FLOAT64: {
      float v[4];
      if (!color.ConvertValue<float>(index, std::int8_t(n), v)) return false;
      for (int c = 0; c < n; ++c) out[c] = v[c];
      return std::isfinite(out[0]) && std::isfinite(out[1]) && std::isfinite(out[2]) &&
             std::isfinite(out[3]);
    }
    default:
      return false;
  }
}

}  // namespace

ImportedMesh convert_draco_mesh(const draco::Mesh& mesh, const std::string& path) {
  const draco::PointAttribute* position =
      mesh.GetNamedAttribute(draco::GeometryAttribute::POSITION);
  if (position == nullptr || position->num_components() != 3)
    throw ImportError(path + ": Draco mesh has no 3-component POSITION attribute");
  // Draco converts bool attributes by loading each byte as a C++ bool: any byte but 0 or 1 is
  // undefined behaviour (found by import_drc_fuzzer), and no mesh stores positions as bool.
  auto numeric = [](const draco::PointAttribute& a) {
    return a.data_type() != draco::DT_BOOL && a.data_type() != draco::DT_INVALID &&
           a.data_type() < draco::DT_TYPES_COUNT;
  };
  if (!numeric(*position)) throw ImportError(path + ": Draco POSITION is not numeric data");
  const draco::PointAttribute* normal = mesh.GetNamedAttribute(draco::GeometryAttribute::NORMAL);
  if (normal != nullptr && (normal->num_components() != 3 || !numeric(*normal))) normal = nullptr;
  const draco::PointAttribute* color = mesh.GetNamedAttribute(draco::GeometryAttribute::COLOR);
  if (color != nullptr && color->num_components() != 3 && color->num_components() != 4)
    throw ImportError(path + ": Draco COLOR has " + std::to_string(color->num_components()) +
                      " components, not 3 or 4");

  ImportedMesh out;
  const auto point_count = mesh.num_points();
  out.positions.resize(point_count);
  if (normal != nullptr) out.normals.resize(point_count);
  if (color != nullptr) out.colors.resize(point_count);
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
    if (color != nullptr) {
      double rgba[4];
      if (!read_color(*color, color->mapped_index(p), rgba))
        throw ImportError(path + ": Draco COLOR is not finite float, uint8 or uint16 data");
      out.colors[p.value()] = pack_rgba8(rgba[0], rgba[1], rgba[2], rgba[3]);
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
  check_draco_counts(path, bytes);
  draco::Decoder decoder;
  auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
  if (!decoded.ok()) throw ImportError(path + ": Draco: " + decoded.status().error_msg_string());
  std::vector<ImportedMesh> meshes;
  meshes.push_back(convert_draco_mesh(*decoded.value(), path));
  meshes.back().name = "draco";
  return meshes;
}

}  // namespace kiln
