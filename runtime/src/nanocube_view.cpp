// The nanocube view's open: every index checked once, so queries index freely.
#include <algorithm>
#include <string>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/nanocube.hpp"

namespace kiln {

namespace {

struct Walk {
  const Blob& blob;
  const schema::NanocubeDesc& d;
  const std::string& name;
  [[noreturn]] void fail(std::uint32_t section, const std::string& what) const {
    blob.fail_section(section, "nanocube '" + name + "': " + what);
  }
};

std::vector<std::uint64_t> check_dimensions(const Walk& w, std::size_t categories,
                                            std::uint64_t node_count) {
  std::vector<std::uint64_t> out = copy_vector(w.d.dimension_nodes());
  if (w.d.dimension_count() != categories + 1 || out.size() != w.d.dimension_count() + 1)
    w.fail(0, "dimensions do not match the event table's categories");
  if (out.front() != 0 || out.back() != node_count) w.fail(0, "dimension ranges are invalid");
  for (std::size_t i = 1; i < out.size(); ++i)
    if (out[i] <= out[i - 1]) w.fail(0, "a dimension has no node");
  if (w.d.root() >= out[1]) w.fail(0, "root is not a spatial node");
  return out;
}

// Children before parents within the node's dimension, keys increasing and in range, content in
// the next dimension (or a series).
void check_nodes(const Walk& w, const NanocubeView& view,
                 std::span<const format::NanocubeEdge> edges, std::size_t series_count) {
  const auto nodes = view.nodes();
  const auto dims = view.dimension_nodes();
  const auto& table = view.table();
  for (std::size_t d = 0; d + 1 < dims.size(); ++d) {
    const std::uint64_t keys = d == 0 ? 4 : table.categories[d - 1].label_count;
    for (std::uint64_t i = dims[d]; i < dims[d + 1]; ++i) {
      const format::NanocubeNode& n = nodes[i];
      if (n.first_edge > edges.size() || n.edge_count > edges.size() - n.first_edge)
        w.fail(w.d.nodes(), "node " + std::to_string(i) + " has edges out of range");
      for (std::uint64_t e = n.first_edge; e < n.first_edge + n.edge_count; ++e) {
        const format::NanocubeEdge& edge = edges[e];
        if (edge.key >= keys || (e > n.first_edge && edge.key <= edges[e - 1].key) ||
            edge.node < dims[d] || edge.node >= i)
          w.fail(w.d.edges(),
                 "edge " + std::to_string(e) + " of node " + std::to_string(i) + " is invalid");
      }
      const bool last = d + 2 == dims.size();
      if (last ? n.content >= series_count : (n.content < dims[d + 1] || n.content >= dims[d + 2]))
        w.fail(w.d.nodes(), "node " + std::to_string(i) + " has an invalid content");
    }
  }
}

// The spatial dimension is a tree (the builder never shares a spatial node): each node has at
// most one parent, so a traversal from the root visits each node once whatever the edges say.
void check_space_tree(const Walk& w, const NanocubeView& view,
                      std::span<const format::NanocubeEdge> edges) {
  const auto dims = view.dimension_nodes();
  std::vector<char> has_parent(dims[1], 0);
  for (std::uint64_t i = 0; i < dims[1]; ++i) {
    const format::NanocubeNode& n = view.nodes()[i];
    for (std::uint64_t e = n.first_edge; e < n.first_edge + n.edge_count; ++e) {
      if (has_parent[edges[e].node]) w.fail(w.d.edges(), "a spatial node has two parents");
      has_parent[edges[e].node] = 1;
    }
  }
}

void check_series(const Walk& w, std::span<const format::NanocubeSeries> series,
                  std::span<const std::uint32_t> bins, std::span<const std::uint64_t> counts) {
  for (std::size_t s = 0; s < series.size(); ++s) {
    const auto [first, count] = series[s];
    if (first > bins.size() || count > bins.size() - first || count == 0)
      w.fail(w.d.series(), "series " + std::to_string(s) + " is out of range");
    for (std::uint64_t i = first; i < first + count; ++i)
      if (bins[i] >= w.d.bin_count() ||
          (i > first && (bins[i] <= bins[i - 1] || counts[i] < counts[i - 1])))
        w.fail(w.d.series_bins(), "series " + std::to_string(s) + " is not increasing");
  }
}

// The entries [first, first + count) ordered (counts non-increasing, ties by label) with every
// label below `labels`.
bool ranking_ordered(std::span<const format::NanocubeRankEntry> entries, std::uint64_t first,
                     std::uint64_t count, std::uint64_t labels) {
  for (std::uint64_t e = first; e < first + count; ++e) {
    const format::NanocubeRankEntry& x = entries[e];
    const bool ordered = e == first || x.count < entries[e - 1].count ||
                         (x.count == entries[e - 1].count && x.label > entries[e - 1].label);
    if (x.label >= labels || !ordered) return false;
  }
  return true;
}

// One ranking per category and spatial node, inside the entries, labels in range, counts
// non-increasing with ties by label (a forged ranking can make top-k wrong, never unsafe).
// Lists may name the same range (a node with one child shares its child's), but distinct
// non-empty ranges must not overlap, so each entry is read once whatever the bytes say.
void check_rankings(const Walk& w, const NanocubeView& view,
                    std::span<const format::NanocubeRankList> lists,
                    std::span<const format::NanocubeRankEntry> entries) {
  const auto& categories = view.table().categories;
  const std::uint64_t spatial = view.dimension_nodes()[1];
  if (lists.size() != categories.size() * spatial)
    w.fail(w.d.rank_lists(), "has " + std::to_string(lists.size()) +
                                 " rankings, not one per "
                                 "category and spatial node");
  std::vector<std::uint64_t> order;
  for (std::size_t i = 0; i < lists.size(); ++i) {
    const format::NanocubeRankList& l = lists[i];
    if (l.reserved != 0 || l.first > entries.size() || l.count > entries.size() - l.first)
      w.fail(w.d.rank_lists(), "ranking " + std::to_string(i) + " is out of range");
    if (l.count != 0) order.push_back(i);
  }
  auto range = [&](std::uint64_t i) { return std::pair(lists[i].first, lists[i].count); };
  std::sort(order.begin(), order.end(),
            [&](std::uint64_t a, std::uint64_t b) { return range(a) < range(b); });
  std::uint64_t end = 0;  // of the previous distinct range
  for (std::size_t k = 0; k < order.size();) {
    const std::uint64_t i = order[k];
    std::uint64_t labels = categories[i / spatial].label_count;
    std::size_t same = k + 1;
    for (; same < order.size() && range(order[same]) == range(i); ++same)
      labels = std::min<std::uint64_t>(labels, categories[order[same] / spatial].label_count);
    if (lists[i].first < end)
      w.fail(w.d.rank_lists(), "ranking " + std::to_string(i) + " overlaps another");
    if (!ranking_ordered(entries, lists[i].first, lists[i].count, labels))
      w.fail(w.d.rank_entries(), "ranking " + std::to_string(i) + " is not ordered");
    end = lists[i].first + lists[i].count;
    k = same;
  }
}

// Level i's lists start at level_start[i] in a node storing every level (its finest f: at
// first_list + level_start[i] - level_start[f]); the last entry is all levels' lists.
std::vector<std::uint64_t> block_level_starts(const Walk& w) {
  if (!format::nanocube_blocks_valid(w.d.block_shift(), w.d.block_stride(), w.d.block_levels()))
    w.fail(0, "invalid block levels");
  std::vector<std::uint64_t> start(1, 0);
  for (std::uint32_t i = 0; i < w.d.block_levels(); ++i) {
    const std::uint64_t size =
        format::nanocube_block_size(w.d.block_shift(), w.d.block_stride(), i);
    start.push_back(start.back() + format::nanocube_block_count(w.d.bin_count(), size));
  }
  return start;
}

// Each category's indices name lists inside one range of NCBL, categories' ranges in order, so
// each list is checked once against its category's labels. Lists are contiguous in NCBE (each
// entry read once), every entry counts at least one event, counts non-increasing, ties by label.
void check_block_lists(const Walk& w, const EventTableView& table, std::uint64_t spatial,
                       std::span<const std::uint64_t> level_start,
                       std::span<const format::NanocubeBlockIndex> index,
                       std::span<const format::NanocubeRankList> lists,
                       std::span<const format::NanocubeRankEntry> entries) {
  std::uint64_t next = 0;
  for (std::size_t i = 0; i < lists.size(); ++i) {
    const format::NanocubeRankList& l = lists[i];
    if (l.reserved != 0 || l.first != next || l.count > entries.size() - next)
      w.fail(w.d.block_lists(), "block list " + std::to_string(i) + " is out of range");
    for (std::uint64_t e = l.first; e < l.first + l.count; ++e) {
      const format::NanocubeRankEntry& x = entries[e];
      const bool ordered = e == l.first || x.count < entries[e - 1].count ||
                           (x.count == entries[e - 1].count && x.label > entries[e - 1].label);
      if (x.count == 0 || !ordered)
        w.fail(w.d.block_entries(), "block list " + std::to_string(i) + " is not ordered");
    }
    next += l.count;
  }
  const std::uint32_t levels = w.d.block_levels();
  std::uint64_t floor = 0;  // the previous category's lists end here
  for (std::size_t c = 0; c < table.categories.size(); ++c) {
    std::uint64_t lo = lists.size(), hi = floor;
    for (std::uint64_t n = 0; n < spatial; ++n) {
      const format::NanocubeBlockIndex& x = index[c * spatial + n];
      if (x.reserved != 0 || x.finest > levels || (x.finest == levels && x.first_list != 0))
        w.fail(w.d.block_index(), "block index " + std::to_string(c * spatial + n) + " is invalid");
      if (x.finest == levels) continue;
      const std::uint64_t need = level_start[levels] - level_start[x.finest];
      if (x.first_list < floor || x.first_list > lists.size() || need > lists.size() - x.first_list)
        w.fail(w.d.block_index(),
               "block index " + std::to_string(c * spatial + n) + " names lists out of range");
      lo = std::min(lo, x.first_list), hi = std::max(hi, x.first_list + need);
    }
    const std::uint64_t labels = table.categories[c].label_count;
    for (std::uint64_t i = lo; i < hi; ++i)
      for (std::uint64_t e = lists[i].first; e < lists[i].first + lists[i].count; ++e)
        if (entries[e].label >= labels)
          w.fail(w.d.block_entries(), "block list " + std::to_string(i) + " has a bad label");
    floor = hi;
  }
}

}  // namespace

NanocubeView NanocubeView::from_blob(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::NanocubeDesc>(blob, info);
  const Walk w{blob, d, info.name};
  NanocubeView view;
  view.table_ = blob.event_table();
  if (!format::nanocube_grid_valid(d.max_level(), d.time_bin(), d.time_origin(), d.bin_count()))
    w.fail(0, "invalid grid parameters");
  view.grid_ = {d.max_level(), d.time_bin(), d.time_origin(), d.bin_count()};
  view.nodes_ = blob.section_view<format::NanocubeNode>(d.nodes());
  view.edges_ = blob.section_view<format::NanocubeEdge>(d.edges());
  view.series_ = blob.section_view<format::NanocubeSeries>(d.series());
  view.series_bins_ = blob.section_view<std::uint32_t>(d.series_bins());
  view.series_counts_ = blob.section_view<std::uint64_t>(d.series_counts());
  view.rank_lists_ = blob.section_view<format::NanocubeRankList>(d.rank_lists());
  view.rank_entries_ = blob.section_view<format::NanocubeRankEntry>(d.rank_entries());
  view.dimension_nodes_ = check_dimensions(w, view.table_.categories.size(), view.nodes_.size());
  view.root_ = d.root();
  check_nodes(w, view, view.edges_, view.series_.size());
  check_space_tree(w, view, view.edges_);
  check_series(w, view.series_, view.series_bins_, view.series_counts_);
  check_rankings(w, view, view.rank_lists_, view.rank_entries_);
  view.level_start_ = block_level_starts(w);
  view.block_shift_ = d.block_shift(), view.block_stride_ = d.block_stride();
  view.block_levels_ = d.block_levels();
  view.block_index_ = blob.section_view<format::NanocubeBlockIndex>(d.block_index());
  view.block_lists_ = blob.section_view<format::NanocubeRankList>(d.block_lists());
  view.block_entries_ = blob.section_view<format::NanocubeRankEntry>(d.block_entries());
  const std::uint64_t spatial = view.dimension_nodes_[1];
  if (d.block_index() == kNoSection) {
    view.block_levels_ = 0;  // an older blob: rankings over all time only
    view.level_start_.assign(1, 0);
  } else if (view.block_index_.size() != view.table_.categories.size() * spatial) {
    w.fail(d.block_index(), "is not one block index per category and spatial node");
  }
  if (view.block_levels_ > 0)
    check_block_lists(w, view.table_, spatial, view.level_start_, view.block_index_,
                      view.block_lists_, view.block_entries_);
  return view;
}

}  // namespace kiln
