// The ESVO as the compiler registers it: "esvo", its options, and its contribution to a blob:
// words, page headers, block infos, normal attachment, and EsvoDesc with per-level statistics and
// the bytes-per-voxel split.
#include <unistd.h>

#include <cstdio>
#include <limits>
#include <stdexcept>

#include "kiln/compiler/esvo_builder.hpp"
#include "kiln/compiler/structure_builder.hpp"
#include "kiln/formats/esvo.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/schema/manifest_generated.h"
#include "voxel_options.hpp"

namespace kiln {

extern const StructureBuilder kEsvoBuilder;

namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

// A finite number of voxels that esvo_error_bound accepts: at least sqrt(3).
std::string parse_contour_error(std::string_view text) {
  const std::string value = parse_float_in(-kInfinity, kInfinity)(text);
  EsvoBuildOptions options;
  options.contour_error = std::stod(value);
  try {
    esvo_error_bound(options);
  } catch (const std::invalid_argument&) {
    throw std::invalid_argument(
        "must be at least sqrt(3) = 1.732050808 voxels (what a finest voxel guarantees)");
  }
  return value;
}

std::vector<StructureOption> esvo_options() {
  return {
      voxel_resolution_option(),
      {"contour-error", "--contour-error", "2.45",
       "--accel esvo: bound, in finest voxels, on the distance from any hit to the surface; at "
       "least sqrt(3) (larger lets contoured voxels stop higher)",
       false, parse_contour_error},
      {"no-contours", "--no-contours", "false",
       "--accel esvo: plain cubes, subdivided to the finest level", true, parse_switch()},
      memory_budget_option(),
  };
}

std::string summary_of(const FlatEsvo& e, bool contours, double per_leaf, double bound) {
  char line[320];
  std::snprintf(line, sizeof line,
                "%u^3%s: %llu leaves (depth <= %u), %llu descriptors, %llu contours, "
                "%.2f bytes/leaf (hierarchy %.2f, contours %.2f, attachments %.2f), bound %.2f "
                "voxels",
                e.grid.resolution, contours ? "" : " (no contours)",
                (unsigned long long)e.leaf_count, e.max_depth,
                (unsigned long long)e.descriptor_count, (unsigned long long)e.contour_count,
                per_leaf, double(e.hierarchy_bytes) / double(e.leaf_count),
                double(e.contour_bytes) / double(e.leaf_count),
                double(e.attachment_bytes) / double(e.leaf_count), bound);
  return line;
}

BuiltStructure build(const Scene& scene, const StructureRequest& request, unsigned threads) {
  EsvoBuildOptions options;
  options.resolution = request.uint_option("resolution");
  options.contours = !request.switch_option("no-contours");
  options.contour_error = request.double_option("contour-error");
  options.threads = threads;
  options.memory_budget = memory_budget_bytes(request.text_option("memory-budget"));
  options.progress = isatty(STDERR_FILENO) != 0;  // a progress line only for a person watching
  const double bound = esvo_error_bound(options);
  auto storage = std::make_shared<FlatEsvo>(build_esvo(scene, options));
  const FlatEsvo& e = *storage;
  BuiltStructure built;
  built.sections = {raw_section(format::kSectionEsvoWords, e.words),
                    raw_section(format::kSectionEsvoPages, e.pages),
                    raw_section(format::kSectionEsvoBlocks, e.blocks),
                    raw_section(format::kSectionEsvoNormals, e.normals)};
  const bool colors = !e.colors.empty();
  if (colors) built.sections.push_back(raw_section(format::kSectionEsvoColors, e.colors));
  const double per_leaf =
      double(e.hierarchy_bytes + e.contour_bytes + e.attachment_bytes) / double(e.leaf_count);
  built.describe = [storage, bound, per_leaf, colors, contours = options.contours](
                       flatbuffers::FlatBufferBuilder& fbb, std::span<const std::uint32_t> index) {
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
    return std::pair{std::uint8_t(schema::StructureDesc::EsvoDesc), desc.o};
  };
  built.summary = summary_of(e, options.contours, per_leaf, bound);
  built.storage = std::move(storage);
  return built;
}

}  // namespace

const StructureBuilder kEsvoBuilder{"esvo",
                                    "Efficient sparse voxel octree (Laine & Karras 2010)",
                                    InputKind::kTriangles,
                                    esvo_options(),
                                    build,
                                    /*advise_variants=*/{},
                                    /*advise_skip=*/true};

}  // namespace kiln
