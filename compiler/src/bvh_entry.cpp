// The BVH family as the compiler registers it: "bvh" (binned or sweep SAH builder) and "sbvh"
// (spatial splits), their options, and their contribution to a blob: nodes, leaf triangles,
// primitive ids, BvhDesc.
#include <cstdio>

#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/compiler/bvh_collapse.hpp"
#include "kiln/compiler/structure_builder.hpp"
#include "kiln/formats/bvh.hpp"
#include "kiln/schema/manifest_generated.h"

namespace kiln {

extern const StructureBuilder kBvhBuilder, kSbvhBuilder;

namespace {

std::string printf_like(const char* format, unsigned width, unsigned long long nodes, double fill) {
  char line[128];
  std::snprintf(line, sizeof line, format, width, nodes, fill);
  return line;
}

// The options both kinds share, under the same global flags.
std::vector<StructureOption> common_options() {
  return {
      {"bins", "--bvh-bins", "32", "SAH bins (binned builder, SBVH spatial splits)", false,
       parse_uint_in(2, 1024)},
      {"max-leaf", "--bvh-max-leaf", "8", "Leaves larger than this are always split", false,
       parse_uint_in(1, 255)},
      {"traversal-cost", "--bvh-traversal-cost", "1", "SAH node cost", false,
       parse_float_in(0, 1000)},
      {"intersection-cost", "--bvh-intersection-cost", "1", "SAH triangle cost", false,
       parse_float_in(0.001, 1000)},
      {"width", "--bvh-width", "8", "Children per node: 8 (fastest here), 4, or 2 (binary)", false,
       parse_one_of({"2", "4", "8"})},
      {"boxes", "--bvh-boxes", "float",
       "Wide child boxes: float (fastest here), or u8 (8 bits per plane relative to the node: "
       "half the node bytes)",
       false, parse_one_of({"float", "u8"})},
  };
}

std::vector<StructureOption> bvh_options() {
  std::vector<StructureOption> options = common_options();
  options.insert(options.begin(), {"builder", "--bvh-builder", "binned", "Builder for --accel bvh",
                                   false, parse_one_of({"binned", "sweep"})});
  return options;
}

std::vector<StructureOption> sbvh_options() {
  std::vector<StructureOption> options = common_options();
  options.push_back({"alpha", "--sbvh-alpha", "1e-05",
                     "Try spatial splits when child overlap exceeds alpha x root area", false,
                     parse_float_in(0, 1)});
  options.push_back({"max-duplication", "--sbvh-max-duplication", "1",
                     "At most (1 + this) x triangles references", false, parse_float_in(0, 16)});
  return options;
}

// The options both kinds read; the caller sets the builder and its own options.
BvhBuildOptions common_options_of(const StructureRequest& request, unsigned threads) {
  BvhBuildOptions o;
  o.bins = request.uint_option("bins");
  o.max_leaf_size = request.uint_option("max-leaf");
  o.traversal_cost = request.float_option("traversal-cost");
  o.intersection_cost = request.float_option("intersection-cost");
  o.width = request.uint_option("width");
  o.quantized = request.text_option("boxes") == "u8";
  o.threads = threads;
  return o;
}

std::string summary_of(const BvhStatistics& s, double bytes_per_triangle) {
  char line[256];
  std::snprintf(line, sizeof line,
                "%llu nodes, depth %u, SAH cost %.3f, %.3f references/triangle, %.1f "
                "bytes/triangle",
                (unsigned long long)s.node_count, s.max_depth, s.sah_cost, s.duplication_factor,
                bytes_per_triangle);
  return line;
}

// The binary layout: BVHN, BVHT, BVHP.
BuiltStructure binary_structure(std::shared_ptr<FlatBvh> flat, const BvhBuildOptions& o) {
  BuiltStructure built;
  built.sections = {raw_section(format::kSectionBvhNodes, flat->nodes),
                    raw_section(format::kSectionBvhTriangles, flat->triangles),
                    raw_section(format::kSectionBvhPrimIds, flat->prim_ids)};
  const BvhStatistics s = flat->stats;
  built.describe = [o, s](flatbuffers::FlatBufferBuilder& fbb,
                          std::span<const std::uint32_t> index) {
    const auto desc = schema::CreateBvhDescDirect(
        fbb, bvh_builder_name(o.builder), o.bins, o.traversal_cost, o.intersection_cost,
        o.max_leaf_size, o.sbvh_alpha, o.sbvh_max_duplication, index[0], index[1], index[2],
        s.node_count, s.leaf_count, s.reference_count, s.max_depth, s.max_leaf_size,
        s.average_leaf_size, s.duplication_factor, s.sah_cost, s.bytes_per_triangle, 2);
    return std::pair{std::uint8_t(schema::StructureDesc::BvhDesc), desc.o};
  };
  built.summary = summary_of(s, s.bytes_per_triangle);
  built.storage = std::move(flat);
  return built;
}

// The wide layout: BVWN, BVWT, BVHP (one id per packet lane).
BuiltStructure wide_structure(const FlatBvh& flat, const BvhBuildOptions& o,
                              std::size_t triangle_count) {
  auto wide =
      std::make_shared<FlatWideBvh>(collapse_bvh(flat, o.width, triangle_count, o.quantized));
  BuiltStructure built;
  SectionPayload nodes = raw_section(
      o.quantized ? format::kSectionBvhQuantizedNodes : format::kSectionBvhWideNodes, wide->nodes);
  nodes.element_size = std::uint32_t(wide->nodes.size() / wide->stats.node_count);
  nodes.element_count = wide->stats.node_count;
  built.sections = {nodes, raw_section(format::kSectionBvhPackets, wide->packets),
                    raw_section(format::kSectionBvhPrimIds, wide->prim_ids)};
  const BvhStatistics s = flat.stats;
  const WideBvhStatistics w = wide->stats;
  built.describe = [o, s, w](flatbuffers::FlatBufferBuilder& fbb,
                             std::span<const std::uint32_t> index) {
    constexpr std::uint32_t kAbsent = 0xFFFFFFFFu;
    const auto desc = schema::CreateBvhDescDirect(
        fbb, bvh_builder_name(o.builder), o.bins, o.traversal_cost, o.intersection_cost,
        o.max_leaf_size, o.sbvh_alpha, o.sbvh_max_duplication, kAbsent, kAbsent, index[2],
        s.node_count, s.leaf_count, s.reference_count, s.max_depth, s.max_leaf_size,
        s.average_leaf_size, s.duplication_factor, s.sah_cost, w.bytes_per_triangle, o.width,
        index[0], index[1], w.node_count, w.leaf_count, w.packet_count, w.max_depth, w.packet_fill,
        o.quantized);
    return std::pair{std::uint8_t(schema::StructureDesc::BvhDesc), desc.o};
  };
  built.summary =
      summary_of(s, w.bytes_per_triangle) +
      printf_like(o.quantized ? ", %u-wide (8-bit boxes): %llu nodes, %.0f%% packet fill"
                              : ", %u-wide: %llu nodes, %.0f%% packet fill",
                  o.width, (unsigned long long)w.node_count, 100.0 * w.packet_fill);
  built.storage = std::move(wide);
  return built;
}

BuiltStructure build_structure(const Scene& scene, const BvhBuildOptions& options) {
  auto flat = std::make_shared<FlatBvh>(build_bvh(scene, options));
  if (options.width == 2) return binary_structure(std::move(flat), options);
  return wide_structure(*flat, options, scene.triangles.size());
}

BuiltStructure build_binned_or_sweep(const Scene& scene, const StructureRequest& request,
                                     unsigned threads) {
  BvhBuildOptions options = common_options_of(request, threads);
  options.builder =
      request.text_option("builder") == "sweep" ? BvhBuilder::kSweep : BvhBuilder::kBinned;
  return build_structure(scene, options);
}

BuiltStructure build_spatial(const Scene& scene, const StructureRequest& request,
                             unsigned threads) {
  BvhBuildOptions options = common_options_of(request, threads);
  options.builder = BvhBuilder::kSpatial;
  options.sbvh_alpha = request.float_option("alpha");
  options.sbvh_max_duplication = request.float_option("max-duplication");
  return build_structure(scene, options);
}

}  // namespace

const StructureBuilder kBvhBuilder{"bvh", "Bounding volume hierarchy (binned or sweep SAH)",
                                   InputKind::kTriangles, bvh_options(), build_binned_or_sweep};
const StructureBuilder kSbvhBuilder{"sbvh", "BVH with spatial splits (Stich et al. 2009)",
                                    InputKind::kTriangles, sbvh_options(), build_spatial};

}  // namespace kiln
