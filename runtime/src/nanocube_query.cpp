// The nanocube's queries: cover the snapped box with the quadtree's largest inside nodes, follow
// each one's content through the categories (the root's content when a category is not
// filtered, each kept label's otherwise) to series, and count bins with two binary searches.
#include <algorithm>
#include <functional>
#include <map>
#include <queue>
#include <stdexcept>
#include <utility>

#include "kiln/runtime/nanocube.hpp"

namespace kiln {

namespace {
constexpr std::size_t kNoCategory = ~std::size_t(0);
}

std::uint64_t NanocubeView::series_count(std::uint32_t s, std::int64_t b0, std::int64_t b1) const {
  const format::NanocubeSeries range = series_[s];
  const auto bins = series_bins_.subspan(range.first, range.count);
  const auto counts = series_counts_.subspan(range.first, range.count);
  // Events in bins below b: the cumulative count of the last entry before b.
  auto below = [&](std::int64_t b) -> std::uint64_t {
    if (b <= 0) return 0;
    if (b > std::int64_t(0xFFFFFFFFu)) return counts.back();
    const auto it = std::lower_bound(bins.begin(), bins.end(), std::uint32_t(b));
    return it == bins.begin() ? 0 : counts[std::size_t(it - bins.begin()) - 1];
  };
  return b1 <= b0 ? 0 : below(b1) - below(b0);
}

// Calls f(node, level, x, y) for each largest node inside the selection's cells.
template <class F>
void NanocubeView::cover(const ResolvedSelection& r, std::uint32_t node, std::uint32_t level,
                         std::uint64_t x, std::uint64_t y, F&& f) const {
  const std::uint32_t shift = grid_.max_level - level;
  const std::uint64_t x0 = x << shift, x1 = ((x + 1) << shift) - 1;
  const std::uint64_t y0 = y << shift, y1 = ((y + 1) << shift) - 1;
  if (x1 < r.x0 || x0 > r.x1 || y1 < r.y0 || y0 > r.y1) return;
  if ((x0 >= r.x0 && x1 <= r.x1 && y0 >= r.y0 && y1 <= r.y1) || level == grid_.max_level) {
    f(node, level, x, y);
    return;
  }
  const format::NanocubeNode& n = nodes_[node];
  for (std::uint64_t e = n.first_edge; e < n.first_edge + n.edge_count; ++e)
    cover(r, edges_[e].node, level + 1, 2 * x + (edges_[e].key & 1), 2 * y + (edges_[e].key >> 1),
          f);
}

// Calls f(series, label) for each series under `node` (of dimension `dim`) that the filters
// keep; `label` is the code taken in category `by` (kNoCategory: none). With `only` set, category
// `by` follows that one label's edge (a binary search: keys are increasing).
template <class F>
void NanocubeView::leaves(const ResolvedSelection& r, std::size_t dim, std::uint32_t node,
                          std::size_t by, std::uint32_t label, F&& f, std::uint32_t only) const {
  const std::uint32_t content = nodes_[node].content;
  if (dim + 1 == dimension_nodes_.size() - 1) {
    f(content, label);
    return;
  }
  const std::size_t c = dim;  // the next dimension, dim + 1, is category dim
  const format::NanocubeNode& root = nodes_[content];
  if (r.allowed[c].empty() && by != c) {
    leaves(r, dim + 1, content, by, label, f, only);
    return;
  }
  auto edges = edges_.subspan(root.first_edge, root.edge_count);
  if (by == c && only != kAnyLabel) {
    const auto it = std::lower_bound(
        edges.begin(), edges.end(), only,
        [](const format::NanocubeEdge& e, std::uint32_t key) { return e.key < key; });
    if (it == edges.end() || it->key != only) return;
    edges = edges.subspan(std::size_t(it - edges.begin()), 1);
  }
  for (const format::NanocubeEdge& edge : edges) {
    if (!r.allowed[c].empty() && !r.allowed[c][edge.key]) continue;
    leaves(r, dim + 1, edge.node, by, by == c ? edge.key : label, f, only);
  }
}

std::uint64_t NanocubeView::node_count(const ResolvedSelection& r, std::uint32_t node) const {
  std::uint64_t total = 0;
  leaves(r, 0, node, kNoCategory, 0,
         [&](std::uint32_t s, std::uint32_t) { total += series_count(s, r.b0, r.b1); });
  return total;
}

EventSnap NanocubeView::snap(const EventSelection& s) const {
  return resolve_event_selection(s, table_, grid_).snap;
}

std::uint64_t NanocubeView::count(const EventSelection& s) const {
  const ResolvedSelection r = resolve_event_selection(s, table_, grid_);
  std::uint64_t total = 0;
  if (r.empty) return 0;
  cover(r, root_, 0, 0, 0, [&](std::uint32_t node, std::uint32_t, std::uint64_t, std::uint64_t) {
    total += node_count(r, node);
  });
  return total;
}

std::vector<std::pair<std::int64_t, std::uint64_t>> NanocubeView::series(const EventSelection& s,
                                                                         std::int64_t width) const {
  const ResolvedSelection r = resolve_event_selection(s, table_, grid_);
  auto out = empty_series(grid_, r, width);
  const std::int64_t per = width / grid_.time_bin;
  if (r.empty) return out;
  auto add = [&](std::uint32_t id, std::uint32_t) {
    const format::NanocubeSeries range = series_[id];
    std::uint64_t previous = 0;
    for (std::uint64_t i = range.first; i < range.first + range.count; ++i) {
      const std::int64_t bin = series_bins_[i];
      if (bin >= r.b0 && bin < r.b1)
        out[std::size_t((bin - r.b0) / per)].second += series_counts_[i] - previous;
      previous = series_counts_[i];
    }
  };
  cover(r, root_, 0, 0, 0, [&](std::uint32_t node, std::uint32_t, std::uint64_t, std::uint64_t) {
    leaves(r, 0, node, kNoCategory, 0, add);
  });
  return out;
}

std::vector<EventTileCount> NanocubeView::tiles(const EventSelection& s, std::uint32_t zoom) const {
  if (zoom > grid_.max_level)
    throw std::invalid_argument("zoom " + std::to_string(zoom) +
                                " is past the cube's finest level " +
                                std::to_string(grid_.max_level));
  const ResolvedSelection r = resolve_event_selection(s, table_, grid_);
  std::vector<EventTileCount> out;
  if (r.empty) return out;
  const std::uint32_t shift = grid_.max_level - zoom;
  // Nodes coarser than the zoom are split down to it, so each covered node lies in one tile.
  auto visit = [&](auto& self, std::uint32_t node, std::uint32_t level, std::uint64_t x,
                   std::uint64_t y) -> void {
    if (level < zoom) {
      const format::NanocubeNode& n = nodes_[node];
      for (std::uint64_t e = n.first_edge; e < n.first_edge + n.edge_count; ++e)
        self(self, edges_[e].node, level + 1, 2 * x + (edges_[e].key & 1),
             2 * y + (edges_[e].key >> 1));
      return;
    }
    const std::uint64_t n = node_count(r, node);
    if (n == 0) return;
    const auto tx = std::uint32_t(x >> (level - zoom)), ty = std::uint32_t(y >> (level - zoom));
    if (!out.empty() && out.back().x == tx && out.back().y == ty)
      out.back().count += n;
    else
      out.push_back({zoom, tx, ty, n});
  };
  cover(r, root_, 0, 0, 0,
        [&](std::uint32_t node, std::uint32_t level, std::uint64_t x, std::uint64_t y) {
          visit(visit, node, level, x, y);
        });
  (void)shift;
  // Merge tiles met more than once (a tile's covered nodes arrive consecutively in Z order, but
  // sort to be sure) and order by x, then y.
  std::sort(out.begin(), out.end(), [](const EventTileCount& a, const EventTileCount& b) {
    return a.x != b.x ? a.x < b.x : a.y < b.y;
  });
  std::vector<EventTileCount> merged;
  for (const EventTileCount& t : out)
    if (!merged.empty() && merged.back().x == t.x && merged.back().y == t.y)
      merged.back().count += t.count;
    else
      merged.push_back(t);
  return merged;
}

std::uint64_t NanocubeView::label_count(const ResolvedSelection& r, std::uint32_t node,
                                        std::size_t c, std::uint32_t label) const {
  std::uint64_t total = 0;
  leaves(
      r, 0, node, c, 0,
      [&](std::uint32_t s, std::uint32_t) { total += series_count(s, r.b0, r.b1); }, label);
  return total;
}

std::span<const format::NanocubeRankEntry> NanocubeView::ranking(std::size_t c,
                                                                 std::uint32_t node) const {
  const format::NanocubeRankList& list = rank_lists_[c * dimension_nodes_[1] + node];
  return rank_entries_.subspan(list.first, list.count);
}

bool NanocubeView::rankings_consistent() const {
  const ResolvedSelection all = resolve_event_selection({}, table_, grid_);
  std::vector<std::uint64_t> expected;
  for (std::size_t c = 0; c < table_.categories.size(); ++c) {
    expected.assign(table_.categories[c].label_count, 0);
    for (std::uint32_t node = 0; node < dimension_nodes_[1]; ++node) {
      const format::NanocubeNode& n = nodes_[node];
      const auto mine = ranking(c, node);
      std::uint64_t total = 0;
      for (const format::NanocubeRankEntry& e : mine) total += e.count;
      if (n.edge_count == 0) {
        if (total != node_count(all, node)) return false;
        continue;
      }
      for (std::uint64_t e = n.first_edge; e < n.first_edge + n.edge_count; ++e)
        for (const format::NanocubeRankEntry& x : ranking(c, edges_[e].node))
          expected[x.label] += x.count;
      for (const format::NanocubeRankEntry& e : mine) {
        if (expected[e.label] != e.count) return false;
        expected[e.label] = 0;
      }
      for (std::uint64_t e = n.first_edge; e < n.first_edge + n.edge_count; ++e)
        for (const format::NanocubeRankEntry& x : ranking(c, edges_[e].node))
          if (std::exchange(expected[x.label], 0) != 0) return false;  // a label it lacks
    }
  }
  return true;
}

std::vector<EventLabelCount> NanocubeView::topk(const EventSelection& s, std::string_view by,
                                                std::size_t k) const {
  std::size_t counted = 0;
  return topk_counting(s, by, k, counted);
}

// Topkube's top-k (docs/FORMAT.md §24.3), by the cheapest of three exact ways: with no time
// limit and no filter on another category, the covered nodes' rankings ARE the counts (added
// label by label); where the rankings are short (few labels under each node), each node's labels
// are counted along its label edges; otherwise the threshold algorithm walks the rankings.
std::vector<EventLabelCount> NanocubeView::topk_counting(const EventSelection& s,
                                                         std::string_view by, std::size_t k,
                                                         std::size_t& counted) const {
  counted = 0;
  const auto c = table_.category(by);
  if (!c) throw std::invalid_argument("no category '" + std::string(by) + "' in the event table");
  const ResolvedSelection r = resolve_event_selection(s, table_, grid_);
  if (r.empty || k == 0) return {};
  std::vector<std::uint32_t> covered;
  cover(r, root_, 0, 0, 0, [&](std::uint32_t node, std::uint32_t, std::uint64_t, std::uint64_t) {
    covered.push_back(node);
  });
  std::vector<std::span<const format::NanocubeRankEntry>> rankings;
  std::size_t entries = 0;
  for (const std::uint32_t node : covered) {
    rankings.push_back(ranking(*c, node));
    entries += rankings.back().size();
  }
  bool exact = r.b0 <= 0 && r.b1 >= std::int64_t(grid_.bin_count);
  for (std::size_t other = 0; other < r.allowed.size(); ++other)
    exact = exact && (other == *c || r.allowed[other].empty());
  std::vector<std::uint64_t> counts(table_.categories[*c].label_count, 0);
  const std::vector<char>& allowed = r.allowed[*c];
  if (exact) {
    for (const auto& ranked : rankings)
      for (const format::NanocubeRankEntry& e : ranked)
        if (allowed.empty() || allowed[e.label]) counts[e.label] += e.count;
  } else if (entries <= 2 * k * covered.size()) {
    counted = entries;
    return counted_topk(r, *c, k, covered);
  } else {
    return threshold_topk(r, *c, k, covered, rankings, counted);
  }
  return labels_by_count(counts, *c, k);
}

// Each covered node's labels of category c counted along its label edges.
std::vector<EventLabelCount> NanocubeView::counted_topk(
    const ResolvedSelection& r, std::size_t c, std::size_t k,
    std::span<const std::uint32_t> covered) const {
  std::vector<std::uint64_t> counts(table_.categories[c].label_count, 0);
  for (const std::uint32_t node : covered)
    leaves(r, 0, node, c, 0, [&](std::uint32_t series, std::uint32_t label) {
      counts[label] += series_count(series, r.b0, r.b1);
    });
  return labels_by_count(counts, c, k);
}

std::vector<EventLabelCount> NanocubeView::labels_by_count(std::span<const std::uint64_t> counts,
                                                           std::size_t c, std::size_t k) const {
  std::vector<EventLabelCount> all;
  for (std::uint32_t i = 0; i < counts.size(); ++i)
    if (counts[i] != 0) all.push_back({std::string(table_.label(c, i)), counts[i]});
  return top_labels(std::move(all), k);
}

// Fagin's threshold algorithm over the covered nodes' rankings. Walk them in step, depth by
// depth, counting each label met exactly in every covered node (in the selection's time and
// filters). In node j a label not met yet has at most the ranking's count at the next depth
// (rankings count all time, a superset of any selection) and at most what the labels met leave
// of the node's selected events; the sum over nodes bounds it, and the walk stops once k labels
// count strictly more. Where the bound is loose (the selection holds under half of the nodes'
// events: a short interval, a filter) or the walk would read more counts than the nodes' rankings
// hold entries, it counts each node's labels instead: never much more than that plain count.
std::vector<EventLabelCount> NanocubeView::threshold_topk(
    const ResolvedSelection& r, std::size_t c, std::size_t k,
    std::span<const std::uint32_t> covered,
    std::span<const std::span<const format::NanocubeRankEntry>> rankings,
    std::size_t& counted) const {
  std::size_t deepest = 0, entries = 0;
  for (const auto& ranked : rankings) deepest = std::max(deepest, ranked.size());
  for (const auto& ranked : rankings) entries += ranked.size();
  std::vector<std::uint64_t> left(covered.size());  // selected events of node j not yet placed
  std::uint64_t selected = 0, ranked_events = 0;
  for (std::size_t j = 0; j < covered.size(); ++j) selected += left[j] = node_count(r, covered[j]);
  for (const auto& ranked : rankings)
    for (const format::NanocubeRankEntry& e : ranked) ranked_events += e.count;
  // All-time rankings bound a selection holding a small part of the nodes' events loosely: the
  // walk would count most labels, each in every node, costlier than counting each node's own.
  if (2 * selected < ranked_events) return counted_topk(r, c, k, covered);
  const std::vector<char>& allowed = r.allowed[c];
  std::vector<char> met(table_.categories[c].label_count, 0);
  std::vector<EventLabelCount> hits;
  std::priority_queue<std::uint64_t, std::vector<std::uint64_t>, std::greater<>> best;  // k largest
  for (std::size_t depth = 0; depth < deepest; ++depth) {
    for (const auto& ranked : rankings) {
      if (depth >= ranked.size() || met[ranked[depth].label]) continue;
      const std::uint32_t label = ranked[depth].label;
      met[label] = 1;
      if (!allowed.empty() && !allowed[label]) continue;
      if ((counted + 1) * covered.size() > entries) return counted_topk(r, c, k, covered);
      std::uint64_t n = 0;
      for (std::size_t j = 0; j < covered.size(); ++j) {
        const std::uint64_t in_node = label_count(r, covered[j], c, label);
        left[j] -= std::min(left[j], in_node);
        n += in_node;
      }
      ++counted;
      if (n == 0) continue;
      hits.push_back({std::string(table_.label(c, label)), n});
      best.push(n);
      if (best.size() > k) best.pop();
    }
    std::uint64_t bound = 0;
    for (std::size_t j = 0; j < rankings.size(); ++j)
      if (depth + 1 < rankings[j].size())
        bound += std::min<std::uint64_t>(rankings[j][depth + 1].count, left[j]);
    if (bound == 0 || (best.size() == k && best.top() > bound)) break;
  }
  return top_labels(std::move(hits), k);
}

}  // namespace kiln
