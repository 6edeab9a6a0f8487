#include "kiln/compiler/import.hpp"

#include <zstd.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <memory>

#include "import_ply.hpp"
#include "kiln/runtime/checksum.hpp"

namespace kiln {

namespace {

// Inflated inputs beyond this are refused rather than exhausting memory on a zstd bomb.
constexpr unsigned long long kMaxInflatedInput = 8ull << 30;

std::vector<std::byte> read_whole_file(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw ImportError(path + ": " +
                      (std::filesystem::exists(path, ec) ? "not a regular file" : "no such file"));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ImportError(path + ": cannot open for reading");
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) throw ImportError(path + ": cannot read its size");
  std::vector<std::byte> bytes(size);
  if (size > 0 && !in.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(size)))
    throw ImportError(path + ": read failed");
  return bytes;
}

std::vector<std::byte> inflate_zstd(const std::string& path, std::span<const std::byte> stored) {
  const auto size = ZSTD_getFrameContentSize(stored.data(), stored.size());
  if (size == ZSTD_CONTENTSIZE_ERROR) throw ImportError(path + ": not a zstd file");
  if (size == ZSTD_CONTENTSIZE_UNKNOWN) {
    // Streamed frames carry no size: inflate incrementally.
    std::vector<std::byte> out;
    std::unique_ptr<ZSTD_DStream, decltype(&ZSTD_freeDStream)> stream(ZSTD_createDStream(),
                                                                      ZSTD_freeDStream);
    ZSTD_inBuffer input{stored.data(), stored.size(), 0};
    std::vector<std::byte> chunk(ZSTD_DStreamOutSize());
    while (input.pos < input.size) {
      ZSTD_outBuffer output{chunk.data(), chunk.size(), 0};
      const auto rc = ZSTD_decompressStream(stream.get(), &output, &input);
      if (ZSTD_isError(rc)) throw ImportError(path + ": zstd: " + ZSTD_getErrorName(rc));
      out.insert(out.end(), chunk.begin(), chunk.begin() + std::ptrdiff_t(output.pos));
      if (out.size() > kMaxInflatedInput) throw ImportError(path + ": inflates to over 8 GiB");
      if (rc == 0 && input.pos == input.size) break;
    }
    return out;
  }
  if (size > kMaxInflatedInput) throw ImportError(path + ": inflates to over 8 GiB");
  std::vector<std::byte> out(size);
  const auto got = ZSTD_decompress(out.data(), out.size(), stored.data(), stored.size());
  if (ZSTD_isError(got)) throw ImportError(path + ": zstd: " + ZSTD_getErrorName(got));
  if (got != size) throw ImportError(path + ": zstd frame inflated to the wrong size");
  return out;
}

// Assimp 5.2.5 rejects UTF-16 text meshes read from a path; text formats are ASCII at heart, so
// transcoding to UTF-8 first makes them ordinary. Returns empty when there is no UTF-16 BOM.
std::vector<std::byte> utf16_to_utf8(std::span<const std::byte> bytes) {
  if (bytes.size() < 2) return {};
  const auto b0 = std::uint8_t(bytes[0]), b1 = std::uint8_t(bytes[1]);
  const bool big_endian = b0 == 0xFE && b1 == 0xFF;
  if (!big_endian && !(b0 == 0xFF && b1 == 0xFE)) return {};
  auto unit = [&](std::size_t i) -> std::uint32_t {
    const auto hi = std::uint8_t(bytes[i + (big_endian ? 0 : 1)]);
    const auto lo = std::uint8_t(bytes[i + (big_endian ? 1 : 0)]);
    return std::uint32_t(hi) << 8 | lo;
  };
  std::vector<std::byte> out;
  out.reserve(bytes.size() / 2);
  auto put = [&](std::uint32_t c) { out.push_back(std::byte(c)); };
  for (std::size_t i = 2; i + 1 < bytes.size(); i += 2) {
    std::uint32_t c = unit(i);
    if (c >= 0xD800 && c < 0xDC00 && i + 3 < bytes.size()) {
      const std::uint32_t low = unit(i + 2);
      if (low >= 0xDC00 && low < 0xE000) {
        c = 0x10000 + ((c - 0xD800) << 10) + (low - 0xDC00);
        i += 2;
      }
    }
    if (c < 0x80) {
      put(c);
    } else if (c < 0x800) {
      put(0xC0 | c >> 6), put(0x80 | (c & 0x3F));
    } else if (c < 0x10000) {
      put(0xE0 | c >> 12), put(0x80 | (c >> 6 & 0x3F)), put(0x80 | (c & 0x3F));
    } else {
      put(0xF0 | c >> 18), put(0x80 | (c >> 12 & 0x3F)), put(0x80 | (c >> 6 & 0x3F)),
          put(0x80 | (c & 0x3F));
    }
  }
  return out;
}

std::string lower_extension(const std::string& name) {
  std::string ext = std::filesystem::path(name).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return ext;
}

}  // namespace

ImportedFile import_file(const std::string& path) {
  ImportedFile file;
  const std::vector<std::byte> stored = read_whole_file(path);
  file.source = {path, stored.size(), xxh3_64(stored)};
  file.accessed.read.push_back(path);
  if (stored.empty()) throw ImportError(path + ": file is empty");

  std::string inner_name = path;
  std::vector<std::byte> inflated;
  std::span<const std::byte> bytes = stored;
  if (lower_extension(path) == ".zst") {
    inflated = inflate_zstd(path, stored);
    bytes = inflated;
    inner_name = path.substr(0, path.size() - 4);
    if (bytes.empty()) throw ImportError(path + ": inflates to an empty file");
  }
  const std::string ext = lower_extension(inner_name);
  try {
    if (ext == ".gltf" || ext == ".glb")
      file.meshes = import_gltf(inner_name, bytes, ext == ".glb", &file.accessed);
    else if (ext == ".drc")
      file.meshes = import_draco(inner_name, bytes);  // a single file, never a companion
    else if (ext == ".ply")
      file.meshes = import_ply(inner_name, bytes);  // Kiln's reader: Assimp misreads strips
    else if (auto utf8 = utf16_to_utf8(bytes); !utf8.empty())
      file.meshes = import_with_assimp(inner_name, utf8, ext, false, &file.accessed);
    else
      file.meshes = import_with_assimp(inner_name, bytes, ext, inflated.empty(), &file.accessed);
  } catch (const ImportError& e) {
    // Importers name the inner file; report the path the user gave.
    if (inner_name == path) throw;
    throw ImportError(path + ": " + std::string(e.what()).substr(inner_name.size() + 2));
  } catch (const std::bad_alloc&) {
    throw ImportError(path + ": out of memory while importing (file claims absurd sizes?)");
  }
  // One shared guard behind every importer: nothing out of range reaches the scene.
  std::uint64_t triangles = 0, cloud_vertices = 0;
  for (const auto& mesh : file.meshes) {
    triangles += mesh.triangles.size();
    if (mesh.point_cloud) cloud_vertices += mesh.positions.size();
    if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size())
      throw ImportError(path + ": mesh '" + mesh.name + "' has " +
                        std::to_string(mesh.normals.size()) + " normals for " +
                        std::to_string(mesh.positions.size()) + " vertices");
    for (const auto& t : mesh.triangles)
      for (const auto v : t.v)
        if (v >= mesh.positions.size())
          throw ImportError(path + ": mesh '" + mesh.name + "' has vertex index " +
                            std::to_string(v) + " of " + std::to_string(mesh.positions.size()) +
                            " vertices");
  }
  if (triangles == 0 && cloud_vertices == 0)
    throw ImportError(path + ": contains no triangles (and is not a point cloud)");
  normalize_accesses(file.accessed);
  return file;
}

}  // namespace kiln
