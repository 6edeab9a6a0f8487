// The BVH family as the compiler registers it: "bvh" (binned or sweep SAH builder) and "sbvh"
// (spatial splits), their options, and their contribution to a blob: nodes, leaf triangles,
// primitive ids, BvhDesc.
#include <cstdio>

#include "kiln/compiler/bvh_builder.hpp"
#include "kiln/compiler/structure_builder.hpp"
#include "kiln/formats/bvh.hpp"
#include "kiln/schema/manifest_generated.h"

namespace kiln {

extern const StructureBuilder kBvhBuilder, kSbvhBuilder;

namespace {

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
  o.threads = threads;
  return o;
}

BuiltStructure build_structure(const Scene& scene, const BvhBuildOptions& options) {
  auto flat = std::make_shared<FlatBvh>(build_bvh(scene, options));
  BuiltStructure built;
  built.sections = {raw_section(format::kSectionBvhNodes, flat->nodes),
                    raw_section(format::kSectionBvhTriangles, flat->triangles),
                    raw_section(format::kSectionBvhPrimIds, flat->prim_ids)};
  const BvhStatistics s = flat->stats;
  built.describe = [o = options, s](flatbuffers::FlatBufferBuilder& fbb,
                                    std::span<const std::uint32_t> index) {
    const auto desc = schema::CreateBvhDescDirect(
        fbb, bvh_builder_name(o.builder), o.bins, o.traversal_cost, o.intersection_cost,
        o.max_leaf_size, o.sbvh_alpha, o.sbvh_max_duplication, index[0], index[1], index[2],
        s.node_count, s.leaf_count, s.reference_count, s.max_depth, s.max_leaf_size,
        s.average_leaf_size, s.duplication_factor, s.sah_cost, s.bytes_per_triangle);
    return std::pair{std::uint8_t(schema::StructureDesc::BvhDesc), desc.o};
  };
  char line[256];
  std::snprintf(line, sizeof line,
                "%llu nodes, depth %u, SAH cost %.3f, %.3f references/triangle, %.1f "
                "bytes/triangle",
                (unsigned long long)s.node_count, s.max_depth, s.sah_cost, s.duplication_factor,
                s.bytes_per_triangle);
  built.summary = line;
  built.storage = std::move(flat);
  return built;
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
