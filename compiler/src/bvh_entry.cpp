// The BVH family as the compiler registers it: "bvh" (binned or sweep SAH builder) and "sbvh"
// (spatial splits), their options, and their contribution to a blob: nodes, leaf triangles,
// primitive ids, BvhDesc.
#include <charconv>
#include <cstdio>

#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/compiler/bvh_collapse.hpp"
#include "kiln/compiler/structure_builder.hpp"
#include "kiln/formats/bvh.hpp"
#include "kiln/formats/bvh_wide.hpp"
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
      {"bins", "--bvh-bins", "32", "SAH bins (binned: at most, 4 + n/20 for n refs; SBVH spatial)",
       false, parse_uint_in(2, 1024)},
      {"max-leaf", "--bvh-max-leaf", "8", "Leaves larger than this are always split", false,
       parse_uint_in(1, 255)},
      {"traversal-cost", "--bvh-traversal-cost", "1", "SAH node cost", false,
       parse_float_in(0, 1000)},
      {"intersection-cost", "--bvh-intersection-cost", "1", "SAH triangle cost", false,
       parse_float_in(0.001, 1000)},
      {"width", "--bvh-width", "auto",
       "Children per node: auto (16 with float boxes, the fastest here; 8 with u8 boxes), 16, 8, "
       "4, or 2 (binary)",
       false, parse_one_of({"auto", "2", "4", "8", "16"})},
      {"boxes", "--bvh-boxes", "float",
       "Wide child boxes: float (fastest here), or u8 (8 bits per plane relative to the node: "
       "half the node bytes)",
       false, parse_one_of({"float", "u8"})},
  };
}

// "none", or "evh[=FRACTION]" canonicalised with the fraction written out (so the default's
// value enters the cache key).
std::function<std::string(std::string_view)> parse_presplit() {
  return [](std::string_view text) -> std::string {
    if (text == "none") return "none";
    if (text == "evh") {
      char fraction[32];
      const auto end = std::to_chars(fraction, fraction + sizeof fraction, kEvhDefaultThreshold);
      return "evh=" + std::string(fraction, end.ptr);
    }
    if (text.substr(0, 4) != "evh=")
      throw std::invalid_argument("must be none, evh or evh=FRACTION");
    return "evh=" + parse_float_in(0, 1)(text.substr(4));
  };
}

std::vector<StructureOption> bvh_options() {
  std::vector<StructureOption> options = common_options();
  options.insert(options.begin(), {"builder", "--bvh-builder", "binned", "Builder for --accel bvh",
                                   false, parse_one_of({"binned", "sweep"})});
  options.push_back({"presplit", "--bvh-presplit", "none",
                     "Triangle presplit: none, or evh[=FRACTION] (edge volume heuristic: halve "
                     "triangles whose edge box exceeds FRACTION x the scene box volume; 2^-14)",
                     false, parse_presplit()});
  options.push_back({"evh-max-refs", "--bvh-evh-max-refs", "8",
                     "EVH presplit: at most this many references per triangle", false,
                     parse_uint_in(1, 64)});
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
  o.quantized = request.text_option("boxes") == "u8";
  const std::string& width = request.text_option("width");
  o.width = width == "auto" ? (o.quantized ? 8u : 16u) : request.uint_option("width");
  if (o.quantized && o.width == 16)
    throw std::invalid_argument(
        "--bvh-boxes u8 needs --bvh-width 4 or 8 (16-wide nodes are float)");
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
  std::string text = line;
  if (s.presplit_references != 0)
    text += ", EVH presplit " + std::to_string(s.presplit_references) + " build references";
  return text;
}

double parse_presplit_fraction(const std::string& canonical) {  // "evh=FRACTION"
  double value = 0;
  std::from_chars(canonical.data() + 4, canonical.data() + canonical.size(), value);
  return value;
}

// The BvhDesc of either layout: `index` the blob's sections (binary: nodes, triangles, ids; wide:
// the arena), `wide` null for the binary layout.
std::pair<std::uint8_t, std::uint32_t> write_desc(flatbuffers::FlatBufferBuilder& fbb,
                                                  const BvhBuildOptions& o, const BvhStatistics& s,
                                                  std::span<const std::uint32_t> index,
                                                  const WideBvhStatistics* wide) {
  constexpr std::uint32_t kAbsent = 0xFFFFFFFFu;
  const WideBvhStatistics w = wide ? *wide : WideBvhStatistics{};
  const bool evh = o.presplit == BvhPresplit::kEvh;
  const auto desc = schema::CreateBvhDescDirect(
      fbb, bvh_builder_name(o.builder), o.bins, o.traversal_cost, o.intersection_cost,
      o.max_leaf_size, o.sbvh_alpha, o.sbvh_max_duplication, wide ? kAbsent : index[0],
      wide ? kAbsent : index[1], wide ? kAbsent : index[2], s.node_count, s.leaf_count,
      s.reference_count, s.max_depth, s.max_leaf_size, s.average_leaf_size, s.duplication_factor,
      s.sah_cost, wide ? w.bytes_per_triangle : s.bytes_per_triangle, wide ? o.width : 2, kAbsent,
      kAbsent, w.node_count, w.leaf_count, w.packet_count, w.max_depth, w.packet_fill,
      wide && o.quantized, evh ? "evh" : nullptr, evh ? o.evh_threshold : 0.0,
      evh ? o.evh_max_refs : 0, s.presplit_references, wide ? index[0] : kAbsent,
      wide ? w.arena_bytes / format::kBvhArenaUnit : 0);
  return {std::uint8_t(schema::StructureDesc::BvhDesc), desc.o};
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
    return write_desc(fbb, o, s, index, nullptr);
  };
  built.summary = summary_of(s, s.bytes_per_triangle);
  built.storage = std::move(flat);
  return built;
}

// The wide layout: one BVWA section, the arena (the tree by index is dropped here).
BuiltStructure wide_structure(FlatBvh& flat, const BvhBuildOptions& o, const Scene& scene) {
  WideCollapseOptions c;
  c.threads = o.threads;
  c.index_tree = false;     // the blob stores the arena alone
  c.scratch = &flat.spare;  // the build's finished references: pages already touched
  FlatWideBvh collapsed =
      collapse_bvh(flat, o.width, scene.triangles.size(), o.quantized, &scene, c);
  const WideBvhStatistics w = collapsed.stats;
  auto arena = std::make_shared<UninitializedVector<std::byte>>(std::move(collapsed.arena));
  collapsed = {};
  BuiltStructure built;
  SectionPayload section = raw_section(format::kSectionBvhWideArena, *arena);
  section.element_size = format::kBvhArenaUnit;
  section.element_count = arena->size() / format::kBvhArenaUnit;
  built.sections = {section};
  const BvhStatistics s = flat.stats;
  built.describe = [o, s, w](flatbuffers::FlatBufferBuilder& fbb,
                             std::span<const std::uint32_t> index) {
    return write_desc(fbb, o, s, index, &w);
  };
  built.summary =
      summary_of(s, w.bytes_per_triangle) +
      printf_like(o.quantized ? ", %u-wide (8-bit boxes): %llu nodes, %.0f%% packet fill"
                              : ", %u-wide: %llu nodes, %.0f%% packet fill",
                  o.width, (unsigned long long)w.node_count, 100.0 * w.packet_fill);
  built.storage = std::move(arena);
  return built;
}

BuiltStructure build_structure(const Scene& scene, BvhBuildOptions options) {
  // The wide layout takes corners from the scene: no binary leaf triangles at the peak.
  options.leaf_triangles = options.width == 2;
  // The wide layouts pack leaves in 4-triangle packets: the binary tree stops there.
  options.leaf_packet = options.width == 2 ? 0 : format::kBvhPacketSize;
  auto flat = std::make_shared<FlatBvh>(build_bvh(scene, options));
  if (options.width == 2) {
    flat->spare = {};  // no collapse: the binary layout is kept, not its build's scratch
    return binary_structure(std::move(flat), options);
  }
  return wide_structure(*flat, options, scene);
}

BuiltStructure build_binned_or_sweep(const Scene& scene, const StructureRequest& request,
                                     unsigned threads) {
  BvhBuildOptions options = common_options_of(request, threads);
  options.builder =
      request.text_option("builder") == "sweep" ? BvhBuilder::kSweep : BvhBuilder::kBinned;
  const std::string& presplit = request.text_option("presplit");
  if (presplit != "none") {
    options.presplit = BvhPresplit::kEvh;
    options.evh_threshold = parse_presplit_fraction(presplit);
    options.evh_max_refs = request.uint_option("evh-max-refs");
  }
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

const StructureBuilder kBvhBuilder{
    "bvh", "Bounding volume hierarchy (binned or sweep SAH)", InputKind::kTriangles, bvh_options(),
    build_binned_or_sweep,
    // kiln advise: the other layouts of the same tree
    /*advise_variants=*/{"bvh:width=8", "bvh:width=4", "bvh:width=2", "bvh:boxes=u8"}};
const StructureBuilder kSbvhBuilder{"sbvh", "BVH with spatial splits (Stich et al. 2009)",
                                    InputKind::kTriangles, sbvh_options(), build_spatial};

}  // namespace kiln
