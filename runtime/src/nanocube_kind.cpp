// The nanocube kind of the runtime registry ("nanocube"): its manifest checks, view (the
// EventQueries capability), deep check and description.
#include <memory>
#include <string>

#include "kiln/formats/nanocube.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/nanocube.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "text_format.hpp"

namespace kiln {

// format_event_time lives in the compiler; the dump prints times itself.
namespace {

constexpr std::uint32_t kSections[] = {
    format::kSectionNanocubeNodes,        format::kSectionNanocubeEdges,
    format::kSectionNanocubeSeries,       format::kSectionNanocubeSeriesBins,
    format::kSectionNanocubeSeriesCounts, format::kSectionNanocubeRankLists,
    format::kSectionNanocubeRankEntries,  format::kSectionNanocubeBlockIndex,
    format::kSectionNanocubeBlockLists,   format::kSectionNanocubeBlockEntries};

class NanocubeStructure final : public StructureView {
 public:
  explicit NanocubeStructure(NanocubeView view) : view_(std::move(view)) {}
  const EventQueries* events() const override { return &view_; }

 private:
  NanocubeView view_;
};

std::uint64_t elements(const Blob& blob, std::uint32_t section) {
  return section < blob.sections().size() ? blob.sections()[section].element_count : 0;
}

// The block rankings' sections: all three or none (a blob written before them).
void check_blocks(const Blob& blob, const schema::NanocubeDesc& d, const std::string& where) {
  const bool none = d.block_index() == kNoSection;
  if (none != (d.block_lists() == kNoSection) || none != (d.block_entries() == kNoSection))
    blob.fail_section(0, where + "names some block ranking sections, not all three");
  blob.check_section(where + "block index", d.block_index(), format::kSectionNanocubeBlockIndex,
                     sizeof(format::NanocubeBlockIndex), elements(blob, d.block_index()), true);
  blob.check_section(where + "block lists", d.block_lists(), format::kSectionNanocubeBlockLists,
                     sizeof(format::NanocubeRankList), elements(blob, d.block_lists()), true);
  blob.check_section(where + "block entries", d.block_entries(),
                     format::kSectionNanocubeBlockEntries, sizeof(format::NanocubeRankEntry),
                     elements(blob, d.block_entries()), true);
}

std::uint64_t nodes_in(const schema::NanocubeDesc& d) {
  const std::vector<std::uint64_t> dims = copy_vector(d.dimension_nodes());
  return dims.empty() ? 0 : dims.back();
}

void check(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::NanocubeDesc>(blob, info);
  const auto where = "structure '" + info.name + "' ";
  if (d.event_count() != blob.input().vertex_count)
    blob.fail_section(0, where + "counts another number of events than its input");
  // describe() prints the grid's time span without opening the view.
  if (!format::nanocube_grid_valid(d.max_level(), d.time_bin(), d.time_origin(), d.bin_count()))
    blob.fail_section(0, where + "has invalid grid parameters");
  blob.check_section(where + "nodes", d.nodes(), format::kSectionNanocubeNodes,
                     sizeof(format::NanocubeNode), nodes_in(d), false);
  const std::uint64_t edges =
      d.edges() < blob.sections().size() ? blob.sections()[d.edges()].element_count : 0;
  blob.check_section(where + "edges", d.edges(), format::kSectionNanocubeEdges,
                     sizeof(format::NanocubeEdge), edges, false);
  const std::uint64_t series =
      d.series() < blob.sections().size() ? blob.sections()[d.series()].element_count : 0;
  blob.check_section(where + "series", d.series(), format::kSectionNanocubeSeries,
                     sizeof(format::NanocubeSeries), series, false);
  blob.check_section(where + "series bins", d.series_bins(), format::kSectionNanocubeSeriesBins,
                     sizeof(std::uint32_t), d.series_entry_count(), false);
  blob.check_section(where + "series counts", d.series_counts(),
                     format::kSectionNanocubeSeriesCounts, sizeof(std::uint64_t),
                     d.series_entry_count(), false);
  const std::uint64_t lists =
      d.rank_lists() < blob.sections().size() ? blob.sections()[d.rank_lists()].element_count : 0;
  blob.check_section(where + "rank lists", d.rank_lists(), format::kSectionNanocubeRankLists,
                     sizeof(format::NanocubeRankList), lists, false);
  const std::uint64_t entries = d.rank_entries() < blob.sections().size()
                                    ? blob.sections()[d.rank_entries()].element_count
                                    : 0;
  blob.check_section(where + "rank entries", d.rank_entries(), format::kSectionNanocubeRankEntries,
                     sizeof(format::NanocubeRankEntry), entries, false);
  check_blocks(blob, d, where);
}

std::unique_ptr<StructureView> open(const Blob& blob, const StructureInfo& info) {
  return std::make_unique<NanocubeStructure>(NanocubeView::from_blob(blob, info));
}

// Beyond open's walk: the root's total equals the number of events.
void verify(const Blob& blob, const StructureInfo& info) {
  const NanocubeView view = NanocubeView::from_blob(blob, info);
  if (view.count({}) != view.table().rows())
    blob.fail("nanocube '" + info.name + "' does not count every event once");
  if (!view.rankings_consistent())
    blob.fail("nanocube '" + info.name + "': a top-k ranking disagrees with the events it ranks");
  if (!view.block_rankings_consistent())
    blob.fail("nanocube '" + info.name +
              "': a time block's top-k ranking disagrees with the events it ranks");
}

std::string utc(std::int64_t t) {
  const std::int64_t days = (t >= 0 ? t : t - 86399) / 86400, rest = t - days * 86400;
  const std::int64_t z = days + 719468, era = (z >= 0 ? z : z - 146096) / 146097;
  const auto doe = unsigned(z - era * 146097);
  const unsigned yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  const unsigned doy = doe - (365 * yoe + yoe / 4 - yoe / 100), mp = (5 * doy + 2) / 153;
  const unsigned day = doy - (153 * mp + 2) / 5 + 1, month = mp < 10 ? mp + 3 : mp - 9;
  const long long year = (long long)(yoe) + era * 400 + (month <= 2);
  return printf_string("%04lld-%02u-%02uT%02d:%02dZ", year, month, day, int(rest / 3600),
                       int(rest / 60 % 60));
}

// The block rankings: levels, lists, entries and their bytes.
void describe_blocks(const Blob& blob, const schema::NanocubeDesc& d, Description& out) {
  const std::uint64_t lists = elements(blob, d.block_lists());
  const std::uint64_t entries = elements(blob, d.block_entries());
  const std::uint64_t bytes = elements(blob, d.block_index()) * sizeof(format::NanocubeBlockIndex) +
                              lists * sizeof(format::NanocubeRankList) +
                              entries * sizeof(format::NanocubeRankEntry);
  std::string sizes;
  const bool valid =
      format::nanocube_blocks_valid(d.block_shift(), d.block_stride(), d.block_levels());
  for (std::uint32_t i = 0; valid && i < d.block_levels(); ++i)
    sizes += (i ? ", " : "") +
             std::to_string(format::nanocube_block_size(d.block_shift(), d.block_stride(), i));
  out.lines.push_back(printf_string(
      "topkube block rankings: blocks of %s bins, under nodes of >= %llu events; %llu lists, "
      "%llu entries, %llu bytes (%.2f bytes/event)",
      sizes.empty() ? "none" : sizes.c_str(), (unsigned long long)d.block_min_events(),
      (unsigned long long)lists, (unsigned long long)entries, (unsigned long long)bytes,
      d.event_count() ? double(bytes) / double(d.event_count()) : 0.0));
  out.field("block_levels", d.block_levels()).field("block_lists", lists);
  out.field("block_entries", entries).field("block_bytes", bytes);
}

Description describe(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::NanocubeDesc>(blob, info);
  const EventTableView table = blob.event_table();
  const std::vector<std::uint64_t> dims = copy_vector(d.dimension_nodes());
  auto nodes = [&](std::size_t i) -> std::uint64_t {
    return i + 1 < dims.size() ? dims[i + 1] - dims[i] : 0;
  };
  Description out;
  const std::int64_t t1 = d.time_origin() + std::int64_t(d.bin_count()) * d.time_bin();
  out.lines.push_back(printf_string("space: quadtree levels 0..%u (Web Mercator), %llu nodes",
                                    d.max_level(), (unsigned long long)nodes(0)));
  DescTable dim_table{"dimensions", {"name", "kind", "labels", "nodes"}, {}};
  dim_table.rows.push_back(
      {std::string("space"), std::string("quadtree"), std::uint64_t(0), std::uint64_t(nodes(0))});
  for (std::size_t c = 0; c < table.categories.size(); ++c) {
    const EventCategoryInfo& cat = table.categories[c];
    std::string labels;
    for (std::uint64_t l = 0; l < cat.label_count && l < 8; ++l)
      labels += (l ? ", " : "") + std::string(table.label(c, std::uint32_t(l)));
    if (cat.label_count > 8) labels += ", ...";
    out.lines.push_back(printf_string("category %s (column %s): %llu labels (%s), %llu nodes",
                                      cat.name.c_str(), cat.column.c_str(),
                                      (unsigned long long)cat.label_count, labels.c_str(),
                                      (unsigned long long)nodes(c + 1)));
    dim_table.rows.push_back({cat.name, std::string(cat.edges.empty() ? "labels" : "bins"),
                              std::uint64_t(cat.label_count), std::uint64_t(nodes(c + 1))});
  }
  out.lines.push_back(
      printf_string("time: %s .. %s, bins of %lld s (%u bins), %llu series, "
                    "%llu entries",
                    utc(d.time_origin()).c_str(), utc(t1).c_str(), (long long)d.time_bin(),
                    d.bin_count(), (unsigned long long)blob.sections()[d.series()].element_count,
                    (unsigned long long)d.series_entry_count()));
  std::uint64_t bytes = 0;
  for (const std::uint32_t s : info.sections)
    bytes += blob.sections()[s].element_count * blob.sections()[s].element_size;
  const double per_event = d.event_count() ? double(bytes) / double(d.event_count()) : 0.0;
  out.lines.push_back(printf_string(
      "sharing %s: %llu shared content links, %llu shared child links; %llu events, %.2f "
      "bytes/event",
      d.sharing() ? "on" : "off", (unsigned long long)d.shared_content_links(),
      (unsigned long long)d.shared_child_links(), (unsigned long long)d.event_count(), per_event));
  out.field("max_level", d.max_level()).field("time_bin", std::uint64_t(d.time_bin()));
  out.field("time_origin", utc(d.time_origin())).field("time_end", utc(t1));
  out.field("bin_count", d.bin_count()).field("sharing", d.sharing());
  out.field("shared_content_links", d.shared_content_links());
  out.field("shared_child_links", d.shared_child_links());
  const std::uint64_t rank_entries = d.rank_entries() < blob.sections().size()
                                         ? blob.sections()[d.rank_entries()].element_count
                                         : 0;
  out.lines.push_back(printf_string("topkube rankings: %llu entries over %llu spatial nodes",
                                    (unsigned long long)rank_entries,
                                    (unsigned long long)nodes(0)));
  out.field("rank_entries", rank_entries);
  describe_blocks(blob, d, out);
  out.field("event_count", d.event_count()).field("bytes", bytes);
  out.field("bytes_per_event", per_event);
  out.tables.push_back(std::move(dim_table));
  return out;
}

}  // namespace

extern const StructureKind kNanocubeKind;

const StructureKind kNanocubeKind{"nanocube",
                                  "nanocube over an event table: count, series, tiles, top-k",
                                  InputKind::kEvents,
                                  kSections,
                                  std::uint8_t(schema::StructureDesc::NanocubeDesc),
                                  check,
                                  open,
                                  verify,
                                  describe};

}  // namespace kiln
