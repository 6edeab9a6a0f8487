// Builds the nanocube in one recursive pass over an index permutation of the events. A call
// gets the events of one node (contiguous in the permutation) as runs, each run the events of
// one part built before (a child of the node whose content this is, or that child's node at the
// same address) with that part's node as its hint. A node fed by a single hinted run IS that
// node: a shared child link. A node with a single child takes the child's content: a shared
// content link. Only nodes mixing several parts are built anew, which is the paper's sharing.
#include <algorithm>
#include <limits>
#include <span>
#include <stdexcept>
#include <utility>

#include "kiln/compiler/nanocube_builder.hpp"

namespace kiln {

namespace {

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

struct Run {
  std::uint32_t hint;  // a node (or series) with exactly this run's events, or kNone
  std::uint64_t length;
};

struct TmpNode {
  std::uint64_t first_edge;
  std::uint32_t edge_count;
  std::uint32_t content;
};

// Events of one child (key) of a node: positions [begin, end) of the node's span after the
// stable partition, as runs of the parent's parts in the parent's order.
struct Group {
  std::uint32_t key;
  std::size_t begin, end;
  std::vector<Run> runs;
};

// Partitions `ev` stably by key (counting sort for few keys, else a sort of positions), using
// `scratch` (same size) as the buffer, and returns the groups in key order.
template <class KeyFn>
std::vector<Group> group_by(std::span<std::uint32_t> ev, const std::vector<Run>& runs,
                            std::uint64_t key_count, KeyFn key, std::span<std::uint32_t> scratch) {
  const std::size_t n = ev.size();
  std::vector<std::uint32_t> keys(n), run_of(n), order(n);
  for (std::size_t r = 0, p = 0; r < runs.size(); ++r)
    for (std::uint64_t j = 0; j < runs[r].length; ++j) run_of[p++] = std::uint32_t(r);
  for (std::size_t i = 0; i < n; ++i) keys[i] = key(ev[i]);
  if (key_count <= 64 || key_count <= n) {
    std::vector<std::size_t> start(key_count + 1, 0);
    for (std::size_t i = 0; i < n; ++i) ++start[keys[i] + 1];
    for (std::size_t k = 0; k < key_count; ++k) start[k + 1] += start[k];
    for (std::size_t i = 0; i < n; ++i) order[start[keys[i]]++] = std::uint32_t(i);
  } else {
    for (std::size_t i = 0; i < n; ++i) order[i] = std::uint32_t(i);
    std::stable_sort(order.begin(), order.end(),
                     [&](std::uint32_t a, std::uint32_t b) { return keys[a] < keys[b]; });
  }
  for (std::size_t i = 0; i < n; ++i) scratch[i] = ev[order[i]];
  std::copy(scratch.begin(), scratch.end(), ev.begin());
  std::vector<Group> groups;
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t k = keys[order[i]], r = run_of[order[i]];
    const bool new_group = groups.empty() || groups.back().key != k;
    if (new_group) groups.push_back({k, i, i, {}});
    Group& g = groups.back();
    if (new_group || run_of[order[i - 1]] != r) g.runs.push_back({runs[r].hint, 0});
    ++g.runs.back().length;
    g.end = i + 1;
  }
  return groups;
}

// One block level's (label, count) pairs under a node: block b's are entries[start[b] ..
// start[b + 1]), unsorted.
struct LevelRanks {
  std::vector<format::NanocubeRankEntry> entries;
  std::vector<std::uint64_t> start;
};

class CubeBuilder {
 public:
  CubeBuilder(const EventTable& table, const NanocubeOptions& options, NanocubeData& out)
      : table_(table), options_(options), out_(out), dims_(1 + table.categories.size()) {}

  void run();

 private:
  std::uint32_t space(std::uint32_t level, std::span<std::uint32_t> ev, std::vector<Run> runs);
  std::uint32_t category(std::size_t dim, std::span<std::uint32_t> ev, std::vector<Run> runs);
  std::uint32_t label_leaf(std::size_t dim, std::span<std::uint32_t> ev, std::vector<Run> runs);
  std::uint32_t content(std::size_t dim, std::span<std::uint32_t> ev, std::vector<Run> runs);
  std::uint32_t series(std::span<const std::uint32_t> ev, const std::vector<Run>& runs);
  std::uint32_t add_node(std::size_t dim, std::span<const format::NanocubeEdge> edges,
                         std::uint32_t content);
  void rank(std::span<const std::uint32_t> ev, std::span<const format::NanocubeEdge> children);
  format::NanocubeBlockIndex rank_blocks(std::size_t c, std::span<const std::uint32_t> ev);
  void rank_level(std::size_t c, std::span<const std::uint32_t> ev, LevelRanks& out);
  void coarser_level(std::size_t c, const LevelRanks& fine, LevelRanks& out);
  void emit_block_lists(std::size_t c, const std::vector<LevelRanks>& levels, std::uint32_t finest);
  std::uint32_t child_of(std::size_t dim, std::uint32_t node, std::uint32_t key) const;
  // A shared child link: the runs are one part built before.
  bool shared(const std::vector<Run>& runs) {
    if (!options_.sharing || runs.size() != 1 || runs[0].hint == kNone) return false;
    ++out_.shared_child_links;
    return true;
  }
  std::uint32_t content_of(std::size_t dim, std::uint32_t node) const {
    return node == kNone ? kNone : nodes_[dim][node].content;
  }
  void flatten();
  std::span<std::uint32_t> scratch_of(std::span<std::uint32_t> ev) {
    return std::span(scratch_).subspan(std::size_t(ev.data() - perm_.data()), ev.size());
  }

  const EventTable& table_;
  const NanocubeOptions& options_;
  NanocubeData& out_;
  std::size_t dims_;
  std::vector<std::uint32_t> perm_, scratch_, cx_, cy_, bin_;
  std::vector<std::vector<TmpNode>> nodes_;
  std::vector<std::vector<format::NanocubeEdge>> edges_;
  std::vector<std::vector<format::NanocubeRankList>> ranks_;     // per category, per spatial node
  std::vector<std::vector<std::uint32_t>> tally_;                // per category, per label: zeros
  std::vector<std::vector<format::NanocubeBlockIndex>> blocks_;  // per category, per spatial node
  std::vector<std::uint32_t> seen_;                              // labels met while tallying
  // Per category: its block lists (entries indices local to the category) and entries, written
  // category after category at the end so open can check each category's labels once.
  std::vector<std::vector<format::NanocubeRankList>> block_lists_;
  std::vector<std::vector<format::NanocubeRankEntry>> block_entries_;
};

// Topkube's stored rankings of the spatial node about to be added: per category, its events'
// labels by count. A node with one child has that child's events, so (with sharing) it shares
// the child's entries.
void CubeBuilder::rank(std::span<const std::uint32_t> ev,
                       std::span<const format::NanocubeEdge> children) {
  const std::size_t rows = table_.rows();
  std::vector<std::uint32_t> seen;
  for (std::size_t c = 0; c + 1 < dims_; ++c) {
    if (options_.sharing && children.size() == 1) {
      ranks_[c].push_back(ranks_[c][children[0].node]);
      blocks_[c].push_back(blocks_[c][children[0].node]);
      continue;
    }
    std::vector<std::uint32_t>& tally = tally_[c];
    seen.clear();
    for (const std::uint32_t e : ev)
      if (tally[table_.codes[c * rows + e]]++ == 0) seen.push_back(table_.codes[c * rows + e]);
    const std::size_t first = out_.rank_entries.size();
    for (const std::uint32_t code : seen) {
      out_.rank_entries.push_back({code, tally[code]});
      tally[code] = 0;
    }
    std::sort(out_.rank_entries.begin() + std::ptrdiff_t(first), out_.rank_entries.end(),
              [](const format::NanocubeRankEntry& a, const format::NanocubeRankEntry& b) {
                return a.count != b.count ? a.count > b.count : a.label < b.label;
              });
    ranks_[c].push_back({first, std::uint32_t(seen.size()), 0});
    const bool big =
        ev.size() >= options_.block_min_events && seen.size() >= options_.block_min_labels;
    blocks_[c].push_back(big ? rank_blocks(c, ev)
                             : format::NanocubeBlockIndex{0, out_.block_levels, 0});
  }
}

// Level 0's pairs from the events: bucketed by block (a counting sort), each block's labels
// tallied.
void CubeBuilder::rank_level(std::size_t c, std::span<const std::uint32_t> ev, LevelRanks& out) {
  const std::size_t rows = table_.rows();
  const std::uint32_t shift = out_.block_shift;
  const std::uint64_t blocks =
      format::nanocube_block_count(out_.bin_count, format::nanocube_block_size(shift, 1, 0));
  std::vector<std::uint64_t> at(blocks + 1, 0);
  for (const std::uint32_t e : ev) ++at[(bin_[e] >> shift) + 1];
  for (std::uint64_t b = 0; b < blocks; ++b) at[b + 1] += at[b];
  std::vector<std::uint32_t> codes(ev.size());
  std::vector<std::uint64_t> fill(at.begin(), at.end() - 1);
  for (const std::uint32_t e : ev) codes[fill[bin_[e] >> shift]++] = table_.codes[c * rows + e];
  std::vector<std::uint32_t>& tally = tally_[c];
  out.start.assign(1, 0);
  for (std::uint64_t b = 0; b < blocks; ++b) {
    seen_.clear();
    for (std::uint64_t i = at[b]; i < at[b + 1]; ++i)
      if (tally[codes[i]]++ == 0) seen_.push_back(codes[i]);
    for (const std::uint32_t code : seen_)
      out.entries.push_back({code, std::exchange(tally[code], 0)});
    out.start.push_back(out.entries.size());
  }
}

// A coarser level's pairs: each block's 2^stride finer blocks' pairs tallied.
void CubeBuilder::coarser_level(std::size_t c, const LevelRanks& fine, LevelRanks& out) {
  std::vector<std::uint32_t>& tally = tally_[c];
  const std::uint64_t fine_blocks = fine.start.size() - 1, per = std::uint64_t(1)
                                                                 << out_.block_stride;
  out.start.assign(1, 0);
  for (std::uint64_t b = 0; b * per < fine_blocks; ++b) {
    seen_.clear();
    const std::uint64_t end = fine.start[std::min(fine_blocks, (b + 1) * per)];
    for (std::uint64_t i = fine.start[b * per]; i < end; ++i) {
      const format::NanocubeRankEntry& e = fine.entries[i];
      if (tally[e.label] == 0) seen_.push_back(e.label);
      tally[e.label] += e.count;
    }
    for (const std::uint32_t code : seen_)
      out.entries.push_back({code, std::exchange(tally[code], 0)});
    out.start.push_back(out.entries.size());
  }
}

// Topkube's rankings over time of one node and category: every level's blocks, then the finest
// levels dropped until the rest fits block_bytes_per_event times the node's events (a node
// whose coarsest level does not fit stores none).
format::NanocubeBlockIndex CubeBuilder::rank_blocks(std::size_t c,
                                                    std::span<const std::uint32_t> ev) {
  const std::uint32_t levels = out_.block_levels;
  if (levels == 0) return {0, 0, 0};
  std::vector<LevelRanks> level(levels);
  rank_level(c, ev, level[0]);
  for (std::uint32_t i = 1; i < levels; ++i) coarser_level(c, level[i - 1], level[i]);
  const double budget = options_.block_bytes_per_event * double(ev.size());
  double bytes = 0;
  std::uint32_t finest = levels;
  while (finest > 0) {
    const LevelRanks& l = level[finest - 1];
    bytes += double(l.entries.size() * sizeof(format::NanocubeRankEntry) +
                    (l.start.size() - 1) * sizeof(format::NanocubeRankList));
    if (bytes > budget) break;
    --finest;
  }
  if (finest == levels) return {0, levels, 0};
  const format::NanocubeBlockIndex index{block_lists_[c].size(), finest, 0};
  emit_block_lists(c, level, finest);
  return index;
}

// Levels finest .. levels - 1 written out, each block's pairs ranked (counts down, then labels).
void CubeBuilder::emit_block_lists(std::size_t c, const std::vector<LevelRanks>& levels,
                                   std::uint32_t finest) {
  auto& entries = block_entries_[c];
  for (std::size_t i = finest; i < levels.size(); ++i) {
    const LevelRanks& l = levels[i];
    for (std::size_t b = 0; b + 1 < l.start.size(); ++b) {
      const std::size_t first = entries.size();
      entries.insert(entries.end(), l.entries.begin() + std::ptrdiff_t(l.start[b]),
                     l.entries.begin() + std::ptrdiff_t(l.start[b + 1]));
      std::sort(entries.begin() + std::ptrdiff_t(first), entries.end(),
                [](const format::NanocubeRankEntry& a, const format::NanocubeRankEntry& b) {
                  return a.count != b.count ? a.count > b.count : a.label < b.label;
                });
      block_lists_[c].push_back({first, std::uint32_t(l.start[b + 1] - l.start[b]), 0});
    }
  }
}

std::uint32_t CubeBuilder::add_node(std::size_t dim, std::span<const format::NanocubeEdge> edges,
                                    std::uint32_t content) {
  auto& list = edges_[dim];
  nodes_[dim].push_back({list.size(), std::uint32_t(edges.size()), content});
  list.insert(list.end(), edges.begin(), edges.end());
  if (nodes_[dim].size() >= kNone) throw std::invalid_argument("nanocube: too many nodes");
  return std::uint32_t(nodes_[dim].size() - 1);
}

std::uint32_t CubeBuilder::child_of(std::size_t dim, std::uint32_t node, std::uint32_t key) const {
  if (node == kNone) return kNone;
  const TmpNode& n = nodes_[dim][node];
  const auto* begin = edges_[dim].data() + n.first_edge;
  const auto* end = begin + n.edge_count;
  const auto* it = std::lower_bound(
      begin, end, key, [](const format::NanocubeEdge& e, std::uint32_t k) { return e.key < k; });
  return it != end && it->key == key ? it->node : kNone;
}

std::uint32_t CubeBuilder::content(std::size_t dim, std::span<std::uint32_t> ev,
                                   std::vector<Run> runs) {
  if (!options_.sharing)
    for (Run& r : runs) r.hint = kNone;
  return dim == dims_ ? series(ev, runs) : category(dim, ev, std::move(runs));
}

std::uint32_t CubeBuilder::space(std::uint32_t level, std::span<std::uint32_t> ev,
                                 std::vector<Run> runs) {
  if (shared(runs)) return runs[0].hint;
  std::vector<format::NanocubeEdge> children;
  std::vector<Run> content_runs;
  if (level < options_.max_level) {
    const std::uint32_t shift = options_.max_level - level - 1;
    const auto groups = group_by(
        ev, runs, 4,
        [&](std::uint32_t e) { return ((cx_[e] >> shift) & 1) | (((cy_[e] >> shift) & 1) << 1); },
        scratch_of(ev));
    for (Group g : groups) {
      for (Run& r : g.runs) r.hint = child_of(0, r.hint, g.key);
      const std::uint32_t id = space(level + 1, ev.subspan(g.begin, g.end - g.begin), g.runs);
      children.push_back({g.key, id});
      content_runs.push_back({content_of(0, id), g.end - g.begin});
    }
  } else {
    for (const Run& r : runs) content_runs.push_back({content_of(0, r.hint), r.length});
  }
  std::uint32_t c = 0;
  if (options_.sharing && children.size() == 1) {
    ++out_.shared_content_links;  // the node's events are its one child's
    c = nodes_[0][children[0].node].content;
  } else {
    c = content(1, ev, std::move(content_runs));
  }
  rank(ev, children);
  return add_node(0, children, c);
}

std::uint32_t CubeBuilder::category(std::size_t dim, std::span<std::uint32_t> ev,
                                    std::vector<Run> runs) {
  if (shared(runs)) return runs[0].hint;
  const std::size_t c = dim - 1, rows = table_.rows();
  const auto groups = group_by(
      ev, runs, table_.categories[c].labels.size(),
      [&](std::uint32_t e) { return table_.codes[c * rows + e]; }, scratch_of(ev));
  std::vector<format::NanocubeEdge> children;
  std::vector<Run> content_runs;
  for (Group g : groups) {
    for (Run& r : g.runs) r.hint = child_of(dim, r.hint, g.key);
    const std::uint32_t id = label_leaf(dim, ev.subspan(g.begin, g.end - g.begin), g.runs);
    children.push_back({g.key, id});
    content_runs.push_back({content_of(dim, id), g.end - g.begin});
  }
  std::uint32_t content_id = 0;
  if (options_.sharing && children.size() == 1) {
    ++out_.shared_content_links;
    content_id = nodes_[dim][children[0].node].content;
  } else {
    content_id = content(dim + 1, ev, std::move(content_runs));
  }
  return add_node(dim, children, content_id);
}

std::uint32_t CubeBuilder::label_leaf(std::size_t dim, std::span<std::uint32_t> ev,
                                      std::vector<Run> runs) {
  if (shared(runs)) return runs[0].hint;
  for (Run& r : runs) r.hint = content_of(dim, r.hint);
  return add_node(dim, {}, content(dim + 1, ev, std::move(runs)));
}

// A new series: the hinted runs' series merged (their entries, not their events), the others'
// events counted per bin.
std::uint32_t CubeBuilder::series(std::span<const std::uint32_t> ev, const std::vector<Run>& runs) {
  if (shared(runs)) return runs[0].hint;
  std::vector<std::uint64_t> packed;  // bin << 32 | count
  std::size_t p = 0;
  for (const Run& r : runs) {
    if (r.hint != kNone) {
      const format::NanocubeSeries s = out_.series[r.hint];
      std::uint64_t previous = 0;
      for (std::uint64_t i = s.first; i < s.first + s.count; ++i) {
        packed.push_back(std::uint64_t(out_.series_bins[i]) << 32 |
                         (out_.series_counts[i] - previous));
        previous = out_.series_counts[i];
      }
    } else {
      for (std::size_t i = p; i < p + r.length; ++i)
        packed.push_back(std::uint64_t(bin_[ev[i]]) << 32 | 1);
    }
    p += r.length;
  }
  std::sort(packed.begin(), packed.end());
  const std::uint64_t first = out_.series_bins.size();
  std::uint64_t total = 0;
  for (const std::uint64_t e : packed) {
    const auto bin = std::uint32_t(e >> 32);
    total += e & 0xFFFFFFFFu;
    if (out_.series_bins.size() > first && out_.series_bins.back() == bin)
      out_.series_counts.back() = total;
    else
      out_.series_bins.push_back(bin), out_.series_counts.push_back(total);
  }
  out_.series.push_back({first, out_.series_bins.size() - first});
  if (out_.series.size() >= kNone) throw std::invalid_argument("nanocube: too many series");
  return std::uint32_t(out_.series.size() - 1);
}

void CubeBuilder::run() {
  const std::size_t rows = table_.rows();
  if (rows == 0 || rows >= kNone) throw std::invalid_argument("nanocube: need 1 to 2^32-2 events");
  if (options_.max_level > format::kNanocubeMaxLevel || options_.time_bin <= 0)
    throw std::invalid_argument("nanocube: bad max level or time bin");
  cx_.resize(rows), cy_.resize(rows), bin_.resize(rows);
  const auto [tmin, tmax] = std::minmax_element(table_.times.begin(), table_.times.end());
  const std::int64_t bin = options_.time_bin;
  out_.time_origin = (*tmin >= 0 ? *tmin / bin : -((-*tmin + bin - 1) / bin)) * bin;
  const std::int64_t bins = (*tmax - out_.time_origin) / bin + 1;
  if (bins >= std::int64_t(kNone))
    throw std::invalid_argument("nanocube: more than 2^32 time bins");
  out_.bin_count = std::uint32_t(bins);
  if (!format::nanocube_grid_valid(options_.max_level, bin, out_.time_origin, out_.bin_count))
    throw std::invalid_argument("nanocube: time bin or time span outside the format's range");
  for (std::size_t i = 0; i < rows; ++i) {
    cx_[i] = format::mercator_cell_x(table_.points[i].x, options_.max_level);
    cy_[i] = format::mercator_cell_y(table_.points[i].y, options_.max_level);
    bin_[i] = std::uint32_t((table_.times[i] - out_.time_origin) / bin);
  }
  perm_.resize(rows), scratch_.resize(rows);
  for (std::size_t i = 0; i < rows; ++i) perm_[i] = std::uint32_t(i);
  nodes_.resize(dims_), edges_.resize(dims_), ranks_.resize(dims_ - 1), blocks_.resize(dims_ - 1);
  block_lists_.resize(dims_ - 1), block_entries_.resize(dims_ - 1);
  // Block levels of 2^shift, 2^(shift + stride), ... bins, each smaller than the whole range
  // (the all-time rankings are the range's one block).
  out_.block_shift = options_.block_shift, out_.block_stride = options_.block_stride;
  out_.block_levels = 0;
  while (
      out_.block_levels < format::kNanocubeMaxBlockLevels &&
      format::nanocube_blocks_valid(out_.block_shift, out_.block_stride, out_.block_levels + 1) &&
      format::nanocube_block_size(out_.block_shift, out_.block_stride, out_.block_levels) <
          out_.bin_count)
    ++out_.block_levels;
  for (const auto& category : table_.categories) tally_.emplace_back(category.labels.size(), 0);
  out_.root = space(0, perm_, {{kNone, rows}});
  flatten();
}

// Concatenates the dimensions: node, edge and content indices become global.
void CubeBuilder::flatten() {
  std::vector<std::uint64_t> edge_start(dims_ + 1, 0);
  out_.dimension_nodes.assign(dims_ + 1, 0);
  for (std::size_t d = 0; d < dims_; ++d) {
    out_.dimension_nodes[d + 1] = out_.dimension_nodes[d] + nodes_[d].size();
    edge_start[d + 1] = edge_start[d] + edges_[d].size();
  }
  for (std::size_t d = 0; d < dims_; ++d) {
    for (const TmpNode& n : nodes_[d]) {
      const std::uint64_t next = d + 1 < dims_ ? out_.dimension_nodes[d + 1] : 0;
      out_.nodes.push_back(
          {n.first_edge + edge_start[d], n.edge_count, std::uint32_t(n.content + next)});
    }
    for (const format::NanocubeEdge& e : edges_[d])
      out_.edges.push_back({e.key, std::uint32_t(e.node + out_.dimension_nodes[d])});
    nodes_[d] = {}, edges_[d] = {};
  }
  if (out_.nodes.size() >= kNone) throw std::invalid_argument("nanocube: too many nodes");
  for (auto& lists : ranks_)
    out_.rank_lists.insert(out_.rank_lists.end(), lists.begin(), lists.end());
  ranks_ = {};
  // Block rankings category after category: list and entry indices become global.
  for (std::size_t c = 0; c < blocks_.size(); ++c) {
    const std::uint64_t lists = out_.block_lists.size(), entries = out_.block_entries.size();
    for (format::NanocubeBlockIndex index : blocks_[c]) {
      if (index.finest < out_.block_levels) index.first_list += lists;
      out_.block_index.push_back(index);
    }
    for (format::NanocubeRankList list : block_lists_[c]) {
      list.first += entries;
      out_.block_lists.push_back(list);
    }
    out_.block_entries.insert(out_.block_entries.end(), block_entries_[c].begin(),
                              block_entries_[c].end());
  }
  blocks_ = {}, block_lists_ = {}, block_entries_ = {};
}

}  // namespace

NanocubeData build_nanocube(const EventTable& table, const NanocubeOptions& options) {
  NanocubeData data;
  CubeBuilder(table, options, data).run();
  return data;
}

}  // namespace kiln
