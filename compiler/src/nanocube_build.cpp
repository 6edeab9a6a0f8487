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
  std::vector<std::vector<format::NanocubeRankList>> ranks_;  // per category, per spatial node
  std::vector<std::vector<std::uint32_t>> tally_;             // per category, per label: zeros
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
  nodes_.resize(dims_), edges_.resize(dims_), ranks_.resize(dims_ - 1);
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
}

}  // namespace

NanocubeData build_nanocube(const EventTable& table, const NanocubeOptions& options) {
  NanocubeData data;
  CubeBuilder(table, options, data).run();
  return data;
}

}  // namespace kiln
