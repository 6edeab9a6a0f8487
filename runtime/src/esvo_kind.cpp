// The Efficient Sparse Voxel Octree kind of the runtime registry ("esvo"): its manifest checks,
// view, deep check and description.
#include <algorithm>
#include <bit>
#include <memory>
#include <string>

#include "kiln/formats/esvo.hpp"
#include "kiln/runtime/esvo.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "text_format.hpp"
#include "voxel_structure.hpp"

namespace kiln {

namespace {

constexpr std::uint32_t kSections[] = {format::kSectionEsvoWords, format::kSectionEsvoPages,
                                       format::kSectionEsvoBlocks, format::kSectionEsvoNormals,
                                       format::kSectionEsvoColors};

void check(const Blob& blob, const StructureInfo& info) {
  const auto& e = desc_of<schema::EsvoDesc>(blob, info);
  const auto where = "structure '" + info.name + "' ";
  const std::uint64_t pages =
      (e.word_count() + format::kEsvoPageWords - 1) / format::kEsvoPageWords;
  blob.check_section(where + "words", e.words(), format::kSectionEsvoWords, sizeof(std::uint32_t),
                     e.word_count(), false);
  blob.check_section(where + "page headers", e.pages(), format::kSectionEsvoPages,
                     sizeof(std::uint32_t), pages, false);
  blob.check_section(where + "blocks", e.blocks(), format::kSectionEsvoBlocks,
                     sizeof(format::EsvoBlockInfo), e.block_count(), false);
  blob.check_section(where + "normals", e.normals(), format::kSectionEsvoNormals,
                     sizeof(std::uint32_t), e.voxel_count(), false);
  blob.check_section(where + "colours", e.colors(), format::kSectionEsvoColors,
                     sizeof(std::uint32_t), e.voxel_count(), true);
  // levels is log2(resolution): kiln dump sizes its table by it, so the two must agree.
  if (e.levels() != std::uint32_t(std::bit_width(e.resolution())) - 1)
    blob.fail_section(0, where + "has " + std::to_string(e.levels()) + " levels at resolution " +
                             std::to_string(e.resolution()));
  if (e.level_stats() == nullptr || e.level_stats()->size() != e.levels())
    blob.fail_section(0, where + "has no level table of " + std::to_string(e.levels()) + " levels");
}

std::unique_ptr<StructureView> open(const Blob& blob, const StructureInfo& info) {
  return std::make_unique<VoxelStructure<EsvoView>>(EsvoView::from_blob(blob, info.name));
}

// Beyond the view's walk (which bounds every pointer and refuses contours without a normal):
// the manifest's counts are the tree's.
void verify(const Blob& blob, const StructureInfo& info) {
  const auto& e = desc_of<schema::EsvoDesc>(blob, info);
  const EsvoView::Counts counts = EsvoView::from_blob(blob, info.name).counts();
  if (counts.descriptors != e.descriptor_count() || counts.voxels != e.voxel_count() ||
      counts.leaves != e.leaf_count() || counts.contours != e.contour_count())
    blob.fail_section(e.words(), info.name + " holds " + std::to_string(counts.descriptors) +
                                     " descriptors, " + std::to_string(counts.voxels) +
                                     " voxels, " + std::to_string(counts.leaves) + " leaves, " +
                                     std::to_string(counts.contours) +
                                     " contours; the manifest says otherwise");
}

// The level table: every level in JSON; the human table, as printed since format 1, skips the
// levels without descriptors.
void describe_levels(const schema::EsvoDesc& e, Description& out) {
  out.lines.push_back(printf_string("%5s %14s %14s %14s %14s", "level", "descriptors", "voxels",
                                    "leaves", "contours"));
  DescTable table{"levels_table", {"descriptors", "voxels", "leaves", "contours"}, {}};
  const auto& levels = *e.level_stats();
  for (std::uint32_t l = 0; l < levels.size(); ++l) {
    const auto* s = levels.Get(l);
    table.rows.push_back({s->descriptors(), s->voxels(), s->leaves(), s->contours()});
    if (s->descriptors() == 0) continue;
    out.lines.push_back(
        printf_string("%5u %14llu %14llu %14llu %14llu", l, (unsigned long long)s->descriptors(),
                      (unsigned long long)s->voxels(), (unsigned long long)s->leaves(),
                      (unsigned long long)s->contours()));
  }
  out.tables.push_back(std::move(table));
}

void describe_lines(const schema::EsvoDesc& e, Description& out) {
  const double leaves = double(std::max<std::uint64_t>(1, e.leaf_count()));
  out.lines.push_back(printf_string(
      "%u^3 finest voxels of %g (origin %g, %g, %g), %s, every hit within %.3f voxels of the "
      "surface",
      e.resolution(), e.voxel_size(), e.origin_x(), e.origin_y(), e.origin_z(),
      e.contours() ? "contours" : "no contours (cubes)", e.error_bound_voxels()));
  out.lines.push_back(printf_string(
      "%llu descriptors, %llu voxels, %llu leaves (deepest at level %u), %llu contours, %llu far "
      "pointers, %llu blocks",
      (unsigned long long)e.descriptor_count(), (unsigned long long)e.voxel_count(),
      (unsigned long long)e.leaf_count(), e.max_depth(), (unsigned long long)e.contour_count(),
      (unsigned long long)e.far_pointer_count(), (unsigned long long)e.block_count()));
  out.lines.push_back(printf_string(
      "%.2f bytes/leaf: hierarchy %.2f, contours %.2f, attachments %.2f (normals%s)",
      e.bytes_per_leaf(), double(e.hierarchy_bytes()) / leaves, double(e.contour_bytes()) / leaves,
      double(e.attachment_bytes()) / leaves, e.colors() != kNoSection ? ", colours" : ""));
}

Description describe(const Blob& blob, const StructureInfo& info) {
  const auto& e = desc_of<schema::EsvoDesc>(blob, info);
  const double leaves = double(std::max<std::uint64_t>(1, e.leaf_count()));
  Description out;
  describe_lines(e, out);
  out.field("resolution", e.resolution()).field("levels", e.levels());
  out.field("origin_x", e.origin_x()).field("origin_y", e.origin_y());
  out.field("origin_z", e.origin_z()).field("voxel_size", e.voxel_size());
  out.field("contours", e.contours()).field("error_bound_voxels", e.error_bound_voxels());
  out.field("colors", e.colors() != kNoSection);
  out.field("descriptor_count", e.descriptor_count()).field("voxel_count", e.voxel_count());
  out.field("leaf_count", e.leaf_count()).field("contour_count", e.contour_count());
  out.field("far_pointer_count", e.far_pointer_count()).field("max_depth", e.max_depth());
  out.field("block_count", e.block_count()).field("word_count", e.word_count());
  out.field("hierarchy_bytes", e.hierarchy_bytes()).field("contour_bytes", e.contour_bytes());
  out.field("attachment_bytes", e.attachment_bytes());
  out.field("bytes_per_leaf", e.bytes_per_leaf());
  out.field("hierarchy_bytes_per_leaf", double(e.hierarchy_bytes()) / leaves);
  out.field("contour_bytes_per_leaf", double(e.contour_bytes()) / leaves);
  out.field("attachment_bytes_per_leaf", double(e.attachment_bytes()) / leaves);
  describe_levels(e, out);
  return out;
}

}  // namespace

extern const StructureKind kEsvoKind;

const StructureKind kEsvoKind{"esvo",
                              "sparse voxel octree with contours: rays (voxel hits), occupancy",
                              InputKind::kTriangles,
                              kSections,
                              std::uint8_t(schema::StructureDesc::EsvoDesc),
                              check,
                              open,
                              verify,
                              describe};

}  // namespace kiln
