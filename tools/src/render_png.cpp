// PNG encoding in memory (kiln render writes the bytes with write_file_atomically). stb_image_write
// (Debian's libstb-dev) writes RGB images and supplies the deflate and CRC of the palette images
// written here. It is compiled in this file only, static, so it can never clash with another copy
// in the program.

#include <algorithm>
#include <cstdlib>
#include <memory>
#include <stdexcept>

#include "kiln/tools/render.hpp"
#include "kiln/tools/render_map.hpp"

#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STB_IMAGE_WRITE_STATIC
#define STBI_WRITE_NO_STDIO  // memory only
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wsign-compare"
#include <stb/stb_image_write.h>
#pragma GCC diagnostic pop

namespace kiln::render {

namespace {

void append(void* context, void* data, int size) {
  auto* out = static_cast<std::vector<std::byte>*>(context);
  const auto* bytes = static_cast<const std::byte*>(data);
  out->insert(out->end(), bytes, bytes + size);
}

std::uint32_t packed(const Rgb& c) {
  return std::uint32_t(c.r) << 16 | std::uint32_t(c.g) << 8 | c.b;
}

// Colours of at most 256 distinct values go in a palette PNG: one byte a pixel instead of three,
// which makes noisy heatmaps about three times smaller. The palette is sorted by colour, so the
// bytes depend on the pixels only.
std::vector<std::uint32_t> palette_of(const Image& image) {
  std::vector<std::uint32_t> colours(image.pixels.size());
  for (std::size_t i = 0; i < colours.size(); ++i) colours[i] = packed(image.pixels[i]);
  std::sort(colours.begin(), colours.end());
  colours.erase(std::unique(colours.begin(), colours.end()), colours.end());
  return colours;
}

void put_u32(std::vector<std::byte>& out, std::uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out.push_back(std::byte(v >> shift & 0xFF));
}

void put_chunk(std::vector<std::byte>& out, const char type[4], std::span<const std::byte> data) {
  put_u32(out, std::uint32_t(data.size()));
  const std::size_t start = out.size();
  for (int i = 0; i < 4; ++i) out.push_back(std::byte(type[i]));
  out.insert(out.end(), data.begin(), data.end());
  // The CRC covers the type and the data.
  put_u32(out, stbiw__crc32(reinterpret_cast<unsigned char*>(out.data() + start),
                            int(out.size() - start)));
}

std::vector<std::byte> encode_palette_png(const Image& image,
                                          const std::vector<std::uint32_t>& palette) {
  // Scanlines: filter byte 0 (none, what the PNG spec advises for palette images), indices.
  std::vector<unsigned char> raw;
  raw.reserve((std::size_t(image.width) + 1) * image.height);
  for (std::uint32_t y = 0; y < image.height; ++y) {
    raw.push_back(0);
    for (std::uint32_t x = 0; x < image.width; ++x) {
      const auto it = std::lower_bound(palette.begin(), palette.end(), packed(image.at(x, y)));
      raw.push_back(static_cast<unsigned char>(it - palette.begin()));
    }
  }
  if (raw.size() > std::size_t(INT32_MAX)) throw std::runtime_error("image too large for PNG");
  int zlen = 0;
  const std::unique_ptr<unsigned char, decltype(&std::free)> zlib(
      stbi_zlib_compress(raw.data(), int(raw.size()), &zlen, stbi_write_png_compression_level),
      &std::free);
  if (zlib == nullptr) throw std::runtime_error("PNG encoding failed (out of memory?)");

  std::vector<std::byte> png;
  constexpr unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  for (const unsigned char c : kSignature) png.push_back(std::byte(c));
  std::vector<std::byte> header;
  put_u32(header, image.width);
  put_u32(header, image.height);
  // 8 bits, palette, deflate, adaptive filtering, no interlace.
  constexpr unsigned char kFormat[5] = {8, 3, 0, 0, 0};
  for (const unsigned char c : kFormat) header.push_back(std::byte(c));
  put_chunk(png, "IHDR", header);
  std::vector<std::byte> plte;
  for (const std::uint32_t c : palette)
    for (int shift = 16; shift >= 0; shift -= 8) plte.push_back(std::byte(c >> shift & 0xFF));
  put_chunk(png, "PLTE", plte);
  put_chunk(png, "IDAT", std::as_bytes(std::span(zlib.get(), std::size_t(zlen))));
  put_chunk(png, "IEND", {});
  return png;
}

}  // namespace

std::vector<std::byte> encode_png(const Image& image) {
  static_assert(sizeof(Rgb) == 3);
  if (image.width == 0 || image.height == 0 || image.width > std::uint32_t(INT32_MAX / 3) ||
      image.pixels.size() != std::size_t(image.width) * image.height)
    throw std::runtime_error("cannot encode an empty, malformed or over-wide image");
  if (const auto palette = palette_of(image); palette.size() <= 256)
    return encode_palette_png(image, palette);
  std::vector<std::byte> png;
  if (stbi_write_png_to_func(append, &png, int(image.width), int(image.height), 3,
                             image.pixels.data(), int(image.width * 3)) == 0)
    throw std::runtime_error("PNG encoding failed (out of memory?)");
  return png;
}

std::vector<std::byte> encode_png_rgba(const ImageRgba& image) {
  if (image.width == 0 || image.height == 0 || image.width > std::uint32_t(INT32_MAX / 4) ||
      image.rgba.size() != std::size_t(image.width) * image.height * 4)
    throw std::runtime_error("cannot encode an empty, malformed or over-wide image");
  std::vector<std::byte> png;
  if (stbi_write_png_to_func(append, &png, int(image.width), int(image.height), 4,
                             image.rgba.data(), int(image.width * 4)) == 0)
    throw std::runtime_error("PNG encoding failed (out of memory?)");
  return png;
}

}  // namespace kiln::render
