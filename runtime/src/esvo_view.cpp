#include <bit>
#include <cmath>
#include <string>
#include <vector>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/esvo.hpp"
#include "kiln/runtime/manifest.hpp"
#include "voxel_grid_frame.hpp"

namespace kiln {

namespace {

// Where the attachments of `block` end: the next block's base, or the section's end.
std::uint64_t attachment_end(std::span<const format::EsvoBlockInfo> blocks, std::size_t b,
                             std::uint64_t normal_count) {
  return b + 1 < blocks.size() ? blocks[b + 1].attachment_base : normal_count;
}

}  // namespace

EsvoView::EsvoView(std::span<const std::uint32_t> words, std::span<const std::uint32_t> pages,
                   std::span<const format::EsvoBlockInfo> blocks,
                   std::span<const std::uint32_t> normals, std::span<const std::uint32_t> colors,
                   const VoxelGridFrame& frame, const std::string& name)
    : words_(words),
      pages_(pages),
      blocks_(blocks),
      normals_(normals),
      colors_(colors),
      frame_(frame) {
  auto fail = [&](const std::string& what) { throw BlobError(name + ": " + what); };
  if (const std::string problem = grid_frame_problem(frame); !problem.empty()) fail(problem);
  const std::uint32_t n = frame.resolution;
  levels_ = std::uint32_t(std::bit_width(n) - 1);
  if (words.size() < 2) fail("has no root descriptor");
  if (!colors.empty() && colors.size() != normals.size())
    fail(std::to_string(colors.size()) + " colours for " + std::to_string(normals.size()) +
         " normals");
  if (pages.size() != (words.size() + format::kEsvoPageWords - 1) / format::kEsvoPageWords)
    fail(std::to_string(pages.size()) + " page headers for " + std::to_string(words.size()) +
         " words");
  if (blocks.empty() || blocks[0].first_word != 0 || blocks[0].attachment_base != 0)
    fail("block 0 does not start the words");
  for (std::size_t b = 1; b < blocks.size(); ++b)
    if (blocks[b].first_word <= blocks[b - 1].first_word || blocks[b].first_word >= words.size() ||
        blocks[b].first_word % 2 != 0 ||
        blocks[b].attachment_base < blocks[b - 1].attachment_base ||
        blocks[b].attachment_base > normals.size())
      fail("block " + std::to_string(b) + " is out of order or range");
  for (std::size_t p = 0; p < pages.size(); ++p) {
    const std::uint64_t word = std::uint64_t(p) * format::kEsvoPageWords;
    const std::uint32_t b = pages[p];
    if (b >= blocks.size() || blocks[b].first_word > word ||
        (b + 1 < blocks.size() && blocks[b + 1].first_word <= word))
      fail("page header " + std::to_string(p) + " names the wrong block");
  }

  check_descriptors(name);
}

// Depth-first over every descriptor reachable from the root. Pointers only go forward, so there
// is no cycle, and an octree shares nothing: a descriptor reached twice is refused, so the walk
// (and any later one) is linear in the words.
void EsvoView::check_descriptors(const std::string& name) {
  auto fail = [&](const std::string& what) { throw BlobError(name + ": " + what); };
  std::vector<std::uint8_t> seen(words_.size() / 2);
  std::vector<std::pair<std::uint64_t, std::uint32_t>> stack{{0, 0}};
  seen[0] = 1;
  while (!stack.empty()) {
    const auto [w, level] = stack.back();
    stack.pop_back();
    const format::EsvoDescriptor d = format::decode_descriptor(words_[w], words_[w + 1]);
    counts_.descriptors += 1;
    counts_.voxels += std::popcount(d.valid);
    counts_.leaves += std::popcount(std::uint8_t(d.valid & ~d.non_leaf));
    counts_.contours += std::popcount(d.contour_mask);
    const std::string where = "descriptor at word " + std::to_string(w);
    if ((d.non_leaf & ~d.valid) != 0 || (d.contour_mask & ~d.valid) != 0)
      fail(where + " has non-leaf or contour bits on absent children");
    if (d.valid == 0 && w != 0) fail(where + " has no children");
    if (d.non_leaf != 0 && level + 1 >= levels_) fail(where + " goes deeper than the resolution");
    const std::uint64_t run = w + d.contour_pointer;
    if (d.contour_pointer < 2 || run + 1 + std::popcount(d.contour_mask) > words_.size())
      fail(where + " has its voxel run out of range");
    for (int k = 0; k < std::popcount(d.contour_mask); ++k)
      if (format::contour_extent(format::decode_contour(words_[run + 1 + k])) == 0)
        fail(where + " has a contour without a normal");
    const std::size_t b = block_of(w);
    if (blocks_[b].attachment_base + words_[run] + std::popcount(d.valid) >
        attachment_end(blocks_, b, normals_.size()))
      fail(where + " has attachments outside its block");
    if (d.non_leaf == 0) continue;
    std::uint64_t offset = 2 * std::uint64_t(d.child_pointer);
    if (d.far) {
      if (d.child_pointer < 2 || w + d.child_pointer >= words_.size())
        fail(where + " has its far pointer out of range");
      offset = words_[w + d.child_pointer];
    }
    const std::uint64_t child = w + offset;
    const std::uint64_t count = std::popcount(d.non_leaf);
    if (offset < 2 || offset % 2 != 0 || child + 2 * count > words_.size())
      fail(where + " has its children at word " + std::to_string(child) + ", out of range");
    for (std::uint64_t i = 0; i < count; ++i) {
      const std::uint64_t c = child + 2 * i;
      if (seen[c / 2] != 0) fail(where + " shares a child with another descriptor");
      seen[c / 2] = 1;
      stack.push_back({c, level + 1});
    }
  }
}

EsvoView EsvoView::from_blob(const Blob& blob, const std::string& name) {
  const StructureInfo* info = blob.structure(name);
  const auto* e = info ? structure_table(blob, *info).desc_as<schema::EsvoDesc>() : nullptr;
  if (e == nullptr) blob.fail("has no ESVO '" + name + "'");
  // Blob::open checked kinds, sizes and counts of these sections.
  return EsvoView(
      blob.section_view<std::uint32_t>(e->words()), blob.section_view<std::uint32_t>(e->pages()),
      blob.section_view<format::EsvoBlockInfo>(e->blocks()),
      blob.section_view<std::uint32_t>(e->normals()), blob.section_view<std::uint32_t>(e->colors()),
      grid_frame_of(*e), blob.name() + ": " + name);
}

std::size_t EsvoView::block_of(std::uint64_t w) const {
  std::size_t b = pages_[w / format::kEsvoPageWords];
  while (b + 1 < blocks_.size() && blocks_[b + 1].first_word <= w) ++b;
  return b;
}

std::uint64_t EsvoView::attachment_index(std::uint64_t descriptor_word, std::uint32_t w0,
                                         std::uint32_t w1, std::uint32_t octant) const {
  return blocks_[block_of(descriptor_word)].attachment_base + words_[descriptor_word + (w1 >> 8)] +
         format::rank_below(w0 >> 8 & 0xFF, octant);
}

bool EsvoView::occupied(const format::Float3& point) const {
  const double n = frame_.resolution;
  const double p[3] = {(double(point.x) - frame_.origin[0]) / frame_.voxel_size,
                       (double(point.y) - frame_.origin[1]) / frame_.voxel_size,
                       (double(point.z) - frame_.origin[2]) / frame_.voxel_size};
  for (const double c : p)
    if (!(c >= 0 && c <= n)) return false;
  std::uint64_t w = 0;
  double corner[3] = {0, 0, 0}, side = n;
  for (;;) {
    const std::uint32_t w0 = words_[w], w1 = words_[w + 1];
    side *= 0.5;
    std::uint32_t octant = 0;
    for (int a = 0; a < 3; ++a)
      if (p[a] >= corner[a] + side) octant |= 1u << a, corner[a] += side;
    if ((w0 >> 8 >> octant & 1) == 0) return false;
    if ((w1 >> octant & 1) != 0) {
      // Inside the child's contour slab (formats/esvo.hpp), in grid units.
      const format::Contour c =
          format::decode_contour(words_[w + (w1 >> 8) + 1 + format::rank_below(w1 & 0xFF, octant)]);
      const double unit = format::contour_extent(c) / 128.0;
      double d = 0;
      for (int a = 0; a < 3; ++a) d += c.normal[a] * ((p[a] - corner[a]) / side - 0.5);
      if (d < c.position * unit || d > (c.position + c.thickness) * unit) return false;
    }
    if ((w0 >> octant & 1) == 0) return true;  // a leaf
    w = format::first_child_word(words_.data(), w, w0) + 2 * format::rank_below(w0 & 0xFF, octant);
  }
}

}  // namespace kiln
