#include "draco_extension_check.hpp"

#include "draco_counts_check.hpp"

#include <draco/compression/decode.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "kiln/compiler/import.hpp"

namespace kiln {

namespace {

using nlohmann::json;

std::uint32_t read_u32(std::span<const std::byte> bytes, std::size_t offset) {
  std::uint32_t value;
  std::memcpy(&value, bytes.data() + offset, 4);
  return value;
}

bool is_index(const json& value, std::size_t count) {
  return value.is_number_integer() && value.get<std::int64_t>() >= 0 &&
         std::uint64_t(value.get<std::int64_t>()) < count;
}

std::size_t array_size(const json& root, const char* key) {
  const auto it = root.find(key);
  return it != root.end() && it->is_array() ? it->size() : 0;
}

std::vector<std::byte> read_companion(const std::string& path, const std::string& base_dir,
                                      const std::string& uri, FileAccesses* accessed) {
  if (uri.rfind("data:", 0) == 0)
    throw ImportError(path + ": Draco data in a data: URI is not supported");
  const auto file = std::filesystem::path(base_dir) / uri;
  std::ifstream in(file, std::ios::binary);
  if (!in) throw ImportError(path + ": cannot read buffer '" + uri + "'");
  if (accessed != nullptr) accessed->read.push_back(file.string());
  const std::string text((std::istreambuf_iterator<char>(in)), {});
  std::vector<std::byte> bytes(text.size());
  std::memcpy(bytes.data(), text.data(), text.size());
  return bytes;
}

}  // namespace

GlbChunks split_glb(const std::string& path, std::span<const std::byte> bytes) {
  // GLB: 12-byte header (magic, version, length), then chunks of (length, type, data).
  if (bytes.size() < 20 || std::memcmp(bytes.data(), "glTF", 4) != 0)
    throw ImportError(path + ": not a GLB file");
  GlbChunks chunks;
  std::size_t offset = 12;
  while (offset + 8 <= bytes.size()) {
    const std::uint32_t length = read_u32(bytes, offset);
    const std::uint32_t type = read_u32(bytes, offset + 4);
    if (length > bytes.size() - offset - 8)
      throw ImportError(path + ": GLB chunk runs past the end");
    const auto data = bytes.subspan(offset + 8, length);
    if (type == 0x4E4F534Au && chunks.json.empty())
      chunks.json = {reinterpret_cast<const char*>(data.data()), data.size()};
    else if (type == 0x004E4942u && chunks.bin.empty())
      chunks.bin = data;
    offset += 8 + length;
  }
  if (chunks.json.empty()) throw ImportError(path + ": GLB has no JSON chunk");
  return chunks;
}

void check_draco_extensions(const std::string& path, std::string_view text,
                            std::span<const std::byte> glb_bin, const std::string& base_dir,
                            FileAccesses* accessed) {
  if (text.find("KHR_draco_mesh_compression") == std::string_view::npos) return;
  const json root = json::parse(text.begin(), text.end(), nullptr, false);
  if (root.is_discarded() || !root.is_object()) return;  // tinygltf reports JSON errors itself
  const std::size_t view_count = array_size(root, "bufferViews");
  const std::size_t buffer_count = array_size(root, "buffers");
  const std::size_t accessor_count = array_size(root, "accessors");
  const auto meshes = root.find("meshes");
  if (meshes == root.end() || !meshes->is_array()) return;

  auto fail = [&](const std::string& what) {
    throw ImportError(path + ": KHR_draco_mesh_compression: " + what);
  };
  std::vector<std::vector<std::byte>> companions(buffer_count);
  for (const auto& mesh : *meshes) {
    const auto primitives = mesh.find("primitives");
    if (!mesh.is_object() || primitives == mesh.end() || !primitives->is_array()) continue;
    for (const auto& primitive : *primitives) {
      if (!primitive.is_object() || !primitive.contains("extensions")) continue;
      const auto& extensions = primitive["extensions"];
      if (!extensions.is_object() || !extensions.contains("KHR_draco_mesh_compression")) continue;
      const auto& draco_ext = extensions["KHR_draco_mesh_compression"];
      if (!draco_ext.is_object() || !draco_ext.contains("bufferView") ||
          !is_index(draco_ext["bufferView"], view_count))
        fail("bufferView is missing or out of range");
      if (!draco_ext.contains("attributes") || !draco_ext["attributes"].is_object())
        fail("attributes are missing");
      if (primitive.contains("indices") && !is_index(primitive["indices"], accessor_count))
        fail("indices accessor out of range");
      const auto attributes = primitive.find("attributes");
      if (attributes == primitive.end() || !attributes->is_object())
        fail("primitive has no attributes");

      const auto& view = root["bufferViews"][draco_ext["bufferView"].get<std::size_t>()];
      if (!view.is_object() || !view.contains("buffer") || !is_index(view["buffer"], buffer_count))
        fail("buffer view names no valid buffer");
      const std::size_t buffer_index = view["buffer"].get<std::size_t>();
      const auto& buffer = root["buffers"][buffer_index];
      std::span<const std::byte> buffer_bytes = glb_bin;
      if (buffer.is_object() && buffer.contains("uri") && buffer["uri"].is_string()) {
        if (companions[buffer_index].empty())
          companions[buffer_index] =
              read_companion(path, base_dir, buffer["uri"].get<std::string>(), accessed);
        buffer_bytes = companions[buffer_index];
      }
      // tinygltf keeps a buffer's declared byteLength (a GLB's BIN chunk may hold more) and
      // hands Draco the view unchecked: the view must lie in both.
      const auto declared = buffer.is_object() ? buffer.value("byteLength", json(-1)) : json(-1);
      if (!declared.is_number_integer() || declared.get<std::int64_t>() < 0)
        fail("buffer has no valid byteLength");
      buffer_bytes = buffer_bytes.first(
          std::min<std::uint64_t>(buffer_bytes.size(), declared.get<std::int64_t>()));
      const auto offset = view.value("byteOffset", json(0));
      const auto length = view.value("byteLength", json(0));
      if (!offset.is_number_unsigned() && !offset.is_number_integer()) fail("bad byteOffset");
      if (!length.is_number_unsigned() && !length.is_number_integer()) fail("bad byteLength");
      const auto o = offset.get<std::int64_t>(), n = length.get<std::int64_t>();
      if (o < 0 || n <= 0 || std::uint64_t(o) > buffer_bytes.size() ||
          std::uint64_t(n) > buffer_bytes.size() - std::uint64_t(o))
        fail("buffer view lies outside its buffer");

      check_draco_counts(path, buffer_bytes.subspan(std::size_t(o), std::size_t(n)));
      draco::DecoderBuffer decoder_buffer;
      decoder_buffer.Init(reinterpret_cast<const char*>(buffer_bytes.data()) + o, std::size_t(n));
      draco::Decoder decoder;
      auto decoded = decoder.DecodeMeshFromBuffer(&decoder_buffer);
      if (!decoded.ok()) fail("Draco: " + decoded.status().error_msg_string());
      for (const auto& [name, id] : draco_ext["attributes"].items()) {
        if (!attributes->contains(name) || !is_index((*attributes)[name], accessor_count))
          fail("attribute " + name + " has no valid accessor");
        if (!id.is_number_integer() || id.get<std::int64_t>() < 0 ||
            decoded.value()->GetAttributeByUniqueId(id.get<std::uint32_t>()) == nullptr)
          fail("attribute " + name + " names no attribute in the Draco data");
        const auto& accessor = root["accessors"][(*attributes)[name].get<std::size_t>()];
        const auto type = accessor.is_object() ? accessor.value("componentType", json(0)) : json(0);
        if (!type.is_number_integer() || type.get<int>() < 5120 || type.get<int>() > 5126 ||
            type.get<int>() == 5124)
          fail("attribute " + name + " has an invalid componentType");
      }
      if (primitive.contains("indices")) {
        const auto& accessor = root["accessors"][primitive["indices"].get<std::size_t>()];
        const auto type = accessor.is_object() ? accessor.value("componentType", json(0)) : json(0);
        if (!type.is_number_integer() ||
            (type.get<int>() != 5121 && type.get<int>() != 5123 && type.get<int>() != 5125))
          fail("indices accessor has an invalid componentType");
      }
    }
  }
}

}  // namespace kiln
