// The ESVO's contribution to a blob: words, page headers, block infos, normal attachment, and
// EsvoDesc with per-level statistics and the bytes-per-voxel split.
#include <cstdio>

#include "accel_entry.hpp"
#include "kiln/compiler/esvo_builder.hpp"
#include "kiln/formats/esvo.hpp"
#include "kiln/runtime/blob.hpp"

namespace kiln {

AccelEntry make_esvo_entry(const Scene& scene, const AccelRequest& request, unsigned threads) {
  EsvoBuildOptions options = request.esvo;
  options.threads = threads;
  const double bound = esvo_error_bound(options);
  auto storage = std::make_shared<FlatEsvo>(build_esvo(scene, options));
  const FlatEsvo& e = *storage;
  AccelEntry entry;
  entry.sections = {raw_section(format::kSectionEsvoWords, e.words),
                    raw_section(format::kSectionEsvoPages, e.pages),
                    raw_section(format::kSectionEsvoBlocks, e.blocks),
                    raw_section(format::kSectionEsvoNormals, e.normals)};
  const bool colors = !e.colors.empty();
  if (colors) entry.sections.push_back(raw_section(format::kSectionEsvoColors, e.colors));
  const double per_leaf =
      double(e.hierarchy_bytes + e.contour_bytes + e.attachment_bytes) / double(e.leaf_count);
  entry.describe = [storage, bound, per_leaf, colors, kind = request.kind,
                    contours = options.contours](flatbuffers::FlatBufferBuilder& fbb,
                                                 std::span<const std::uint32_t> index) {
    const FlatEsvo& f = *storage;
    std::vector<flatbuffers::Offset<schema::EsvoLevel>> levels;
    for (const EsvoLevelStats& l : f.level_stats)
      levels.push_back(schema::CreateEsvoLevel(fbb, l.descriptors, l.voxels, l.leaves, l.contours));
    const auto desc = schema::CreateEsvoDescDirect(
        fbb, f.grid.resolution, f.levels, f.grid.origin[0], f.grid.origin[1], f.grid.origin[2],
        f.grid.voxel_size, contours, bound, index[0], index[1], index[2], index[3], &levels,
        f.descriptor_count, f.voxel_count, f.leaf_count, f.contour_count, f.far_pointer_count,
        f.max_depth, f.hierarchy_bytes, f.contour_bytes, f.attachment_bytes, per_leaf,
        f.words.size(), f.blocks.size(), colors ? index[4] : kNoSection);
    const std::vector<std::uint32_t> owned(index.begin(), index.end());
    return schema::CreateAccelerationDirect(fbb, kind.c_str(), &owned, 0, 0, 0, 0, desc);
  };
  char line[320];
  std::snprintf(line, sizeof line,
                "%u^3%s: %llu leaves (depth <= %u), %llu descriptors, %llu contours, "
                "%.2f bytes/leaf (hierarchy %.2f, contours %.2f, attachments %.2f), bound %.2f "
                "voxels",
                e.grid.resolution, options.contours ? "" : " (no contours)",
                (unsigned long long)e.leaf_count, e.max_depth,
                (unsigned long long)e.descriptor_count, (unsigned long long)e.contour_count,
                per_leaf, double(e.hierarchy_bytes) / double(e.leaf_count),
                double(e.contour_bytes) / double(e.leaf_count),
                double(e.attachment_bytes) / double(e.leaf_count), bound);
  entry.summary = line;
  entry.storage = std::move(storage);
  return entry;
}

}  // namespace kiln
