// The nanocube as the compiler registers it: "nanocube" over an event table, its options
// (--max-level, --time-bin, --nanocube-sharing), and its contribution to a blob: nodes, edges,
// series and their entries, NanocubeDesc.
#include <cstdio>
#include <memory>

#include "kiln/compiler/nanocube_builder.hpp"
#include "kiln/compiler/structure_builder.hpp"
#include "kiln/runtime/nanocube.hpp"
#include "kiln/schema/manifest_generated.h"

namespace kiln {

extern const StructureBuilder kNanocubeBuilder;

namespace {

std::vector<StructureOption> nanocube_options() {
  return {
      {"max-level", "--max-level", "20",
       "Nanocube: the quadtree's finest level (Web-Mercator tiles, 0 = the world)", false,
       parse_uint_in(0, format::kNanocubeMaxLevel)},
      {"time-bin", "--time-bin", "3600", "Nanocube: time bin (30s, 15m, 1h, 1d, 1w or seconds)",
       false, [](std::string_view text) { return std::to_string(parse_duration(text)); }},
      {"sharing", "--nanocube-sharing", "on",
       "Nanocube: shared links (off copies every content: same answers, bigger)", false,
       parse_one_of({"on", "off"})},
      {"topk-min-events", "--topk-min-events", "1024",
       "Nanocube: rank labels per block of time bins under spatial nodes of at least this many "
       "events (topkube)",
       false, parse_uint_in(1, 0xFFFFFFFFu)},
      {"topk-min-labels", "--topk-min-labels", "32",
       "Nanocube: ... and at least this many labels of the category", false,
       parse_uint_in(1, 0xFFFFFFFFu)},
      {"topk-block-bytes", "--topk-block-bytes", "6",
       "Nanocube: bytes of block rankings allowed per event of a node and category (the finest "
       "blocks are dropped until they fit)",
       false, parse_uint_in(0, 1024)},
  };
}

BuiltStructure build(const Scene& scene, const StructureRequest& request, unsigned /*threads*/) {
  NanocubeOptions options;
  options.max_level = request.uint_option("max-level");
  options.time_bin = parse_duration(request.text_option("time-bin"));
  options.sharing = request.text_option("sharing") == "on";
  options.block_min_events = request.uint_option("topk-min-events");
  options.block_min_labels = request.uint_option("topk-min-labels");
  options.block_bytes_per_event = request.uint_option("topk-block-bytes");
  auto cube = std::make_shared<NanocubeData>(build_nanocube(*scene.events, options));
  BuiltStructure built;
  built.sections = {raw_section(format::kSectionNanocubeNodes, cube->nodes),
                    raw_section(format::kSectionNanocubeEdges, cube->edges),
                    raw_section(format::kSectionNanocubeSeries, cube->series),
                    raw_section(format::kSectionNanocubeSeriesBins, cube->series_bins),
                    raw_section(format::kSectionNanocubeSeriesCounts, cube->series_counts),
                    raw_section(format::kSectionNanocubeRankLists, cube->rank_lists),
                    raw_section(format::kSectionNanocubeRankEntries, cube->rank_entries),
                    raw_section(format::kSectionNanocubeBlockIndex, cube->block_index),
                    raw_section(format::kSectionNanocubeBlockLists, cube->block_lists),
                    raw_section(format::kSectionNanocubeBlockEntries, cube->block_entries)};
  const std::uint64_t events = scene.events->rows();
  built.describe = [o = options, c = cube.get(), events](flatbuffers::FlatBufferBuilder& fbb,
                                                         std::span<const std::uint32_t> index) {
    const auto desc = schema::CreateNanocubeDescDirect(
        fbb, o.max_level, o.time_bin, c->time_origin, c->bin_count, o.sharing,
        std::uint32_t(c->dimension_nodes.size() - 1), &c->dimension_nodes, c->root,
        c->shared_content_links, c->shared_child_links, events, c->series_bins.size(), index[0],
        index[1], index[2], index[3], index[4], index[5], index[6], c->block_shift, c->block_stride,
        c->block_levels, o.block_min_events, index[7], index[8], index[9]);
    return std::pair{std::uint8_t(schema::StructureDesc::NanocubeDesc), desc.o};
  };
  char line[256];
  std::snprintf(
      line, sizeof line,
      "%llu events, %zu nodes, %zu series (%zu entries), sharing %s (%llu content + "
      "%llu child links), %.1f bytes/event (%.1f of them block rankings)",
      (unsigned long long)events, cube->nodes.size(), cube->series.size(), cube->series_bins.size(),
      options.sharing ? "on" : "off", (unsigned long long)cube->shared_content_links,
      (unsigned long long)cube->shared_child_links, double(cube->bytes()) / double(events),
      double(cube->block_bytes()) / double(events));
  built.summary = line;
  built.storage = std::move(cube);
  return built;
}

}  // namespace

const StructureBuilder kNanocubeBuilder{"nanocube",
                                        "nanocube over an event table (count, series, tiles, "
                                        "top-k); needs --lat --lon --time",
                                        InputKind::kEvents, nanocube_options(), build};

}  // namespace kiln
