#include "kiln/compiler/import.hpp"

#include <zstd.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>

#include "import_ply.hpp"
#include "import_stl.hpp"
#include "kiln/runtime/checksum.hpp"

namespace kiln {

namespace {

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

std::string size_text(std::uint64_t bytes) {
  if (bytes != 0 && bytes % (1u << 30) == 0) return std::to_string(bytes >> 30) + " GiB";
  if (bytes != 0 && bytes % (1u << 20) == 0) return std::to_string(bytes >> 20) + " MiB";
  return std::to_string(bytes) + " bytes";
}

[[noreturn]] void refuse_inflated(const std::string& path, std::uint64_t limit) {
  throw ImportError(path + ": inflates to more than " + size_text(limit) +
                    " (the limit; raise it with --max-inflated-size)");
}

// Inflated bytes in a malloc'd block: glibc grows a large block with mremap, so growing never
// holds the old and the new copy at once and memory stays within the limit.
class InflatedBytes {
 public:
  InflatedBytes() = default;
  std::span<const std::byte> bytes() const { return {data_.get(), size_}; }
  std::size_t capacity() const { return capacity_; }
  std::byte* end() { return data_.get() + size_; }
  void grow_to(std::size_t capacity) {
    void* grown = std::realloc(data_.get(), capacity);
    if (grown == nullptr) throw std::bad_alloc();
    static_cast<void>(data_.release());
    data_.reset(static_cast<std::byte*>(grown));
    capacity_ = capacity;
  }
  void add(std::size_t count) { size_ += count; }

 private:
  struct Free {
    void operator()(std::byte* p) const { std::free(p); }
  };
  std::unique_ptr<std::byte, Free> data_;
  std::size_t size_ = 0, capacity_ = 0;
};

// Streams the frames out, growing the output by doubling but never past the limit, so a bomb
// costs at most `limit` bytes of memory.
InflatedBytes inflate_zstd(const std::string& path, std::span<const std::byte> stored,
                           std::uint64_t limit) {
  const auto declared = ZSTD_getFrameContentSize(stored.data(), stored.size());
  if (declared == ZSTD_CONTENTSIZE_ERROR) throw ImportError(path + ": not a zstd file");
  if (declared != ZSTD_CONTENTSIZE_UNKNOWN && declared > limit) refuse_inflated(path, limit);
  std::unique_ptr<ZSTD_DStream, decltype(&ZSTD_freeDStream)> stream(ZSTD_createDStream(),
                                                                    ZSTD_freeDStream);
  InflatedBytes out;
  out.grow_to(std::max<std::uint64_t>(1, declared != ZSTD_CONTENTSIZE_UNKNOWN
                                             ? declared
                                             : std::min<std::uint64_t>(limit, 1 << 20)));
  ZSTD_inBuffer input{stored.data(), stored.size(), 0};
  std::size_t rc = 1;
  while (input.pos < input.size || rc != 0) {
    if (out.bytes().size() == out.capacity()) {
      if (out.capacity() >= limit) refuse_inflated(path, limit);
      out.grow_to(std::min<std::uint64_t>(limit, std::uint64_t(out.capacity()) * 2));
    }
    ZSTD_outBuffer output{out.end(), out.capacity() - out.bytes().size(), 0};
    const std::size_t before = input.pos;
    rc = ZSTD_decompressStream(stream.get(), &output, &input);
    if (ZSTD_isError(rc)) throw ImportError(path + ": zstd: " + ZSTD_getErrorName(rc));
    out.add(output.pos);
    if (rc != 0 && input.pos == input.size && output.pos < output.size && input.pos == before)
      throw ImportError(path + ": zstd: the file ends inside a frame");
  }
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

// Kiln's STL reader (Assimp 5.2.5 leaks on malformed ASCII STL). A UTF-16 ASCII STL is
// transcoded first, as it was for Assimp; a binary one is never (its header may start FF FE).
std::vector<ImportedMesh> import_stl_text_or_binary(const std::string& path,
                                                    std::span<const std::byte> bytes) {
  if (!is_binary_stl(bytes))
    if (const auto utf8 = utf16_to_utf8(bytes); !utf8.empty()) return import_stl(path, utf8);
  return import_stl(path, bytes);
}

}  // namespace

InputBytes read_input_bytes(const std::string& path, const ImportLimits& limits) {
  auto stored = std::make_shared<std::vector<std::byte>>(read_whole_file(path));
  InputBytes input;
  input.source = {path, stored->size(), xxh3_64(*stored)};
  input.inner_name = path;
  if (stored->empty()) throw ImportError(path + ": file is empty");
  if (lower_extension(path) != ".zst") {
    input.bytes = *stored;
    input.owner = std::move(stored);
    return input;
  }
  auto inflated =
      std::make_shared<InflatedBytes>(inflate_zstd(path, *stored, limits.max_inflated_bytes));
  input.bytes = inflated->bytes();
  input.owner = std::move(inflated);
  input.inner_name = path.substr(0, path.size() - 4);
  if (input.bytes.empty()) throw ImportError(path + ": inflates to an empty file");
  return input;
}

ImportedFile import_file(const std::string& path, const ImportLimits& limits) {
  return import_bytes(path, read_whole_file(path), limits, true);
}

ImportedFile import_bytes(const std::string& path, std::span<const std::byte> stored,
                          const ImportLimits& limits, bool companions) {
  ImportedFile file;
  file.source = {path, stored.size(), xxh3_64(stored)};
  file.accessed.read.push_back(path);
  if (stored.empty()) throw ImportError(path + ": file is empty");

  std::string inner_name = path;
  InflatedBytes inflated;
  std::span<const std::byte> bytes = stored;
  if (lower_extension(path) == ".zst") {
    inflated = inflate_zstd(path, stored, limits.max_inflated_bytes);
    bytes = inflated.bytes();
    inner_name = path.substr(0, path.size() - 4);
    if (bytes.empty()) throw ImportError(path + ": inflates to an empty file");
  }
  const std::string ext = lower_extension(inner_name);
  // Companions are read beside a file read from its path; inflated bytes have no path.
  const bool from_path = companions && inner_name == path;
  try {
    if (ext == ".gltf" || ext == ".glb")
      file.meshes = import_gltf(inner_name, bytes, ext == ".glb", &file.accessed);
    else if (ext == ".drc")
      file.meshes = import_draco(inner_name, bytes);  // a single file, never a companion
    else if (ext == ".ply")
      file.meshes = import_ply(inner_name, bytes);  // Kiln's reader: Assimp misreads strips
    else if (ext == ".stl")
      file.meshes = import_stl_text_or_binary(inner_name, bytes);  // Assimp leaks on bad ASCII
    else if (auto utf8 = utf16_to_utf8(bytes); !utf8.empty())
      file.meshes = ext == ".obj"
                        ? import_obj(inner_name, utf8, false, limits, &file.accessed)
                        : import_with_assimp(inner_name, utf8, ext, false, limits, &file.accessed);
    else if (ext == ".obj")  // Kiln's reader: Assimp's costs 0.66 ms per file, too slow to fuzz
      file.meshes = import_obj(inner_name, bytes, from_path, limits, &file.accessed);
    else
      file.meshes = import_with_assimp(inner_name, bytes, ext, from_path, limits, &file.accessed);
  } catch (const ImportError& e) {
    // Importers name the inner file; report the path the user gave.
    const std::string message = e.what();
    if (inner_name == path || message.rfind(inner_name, 0) != 0) throw;
    throw ImportError(path + message.substr(inner_name.size()));
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
