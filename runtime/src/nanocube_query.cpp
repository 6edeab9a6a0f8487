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

std::vector<std::uint32_t> NanocubeView::covered_nodes(const ResolvedSelection& r) const {
  std::vector<std::uint32_t> covered;
  cover(r, root_, 0, 0, 0, [&](std::uint32_t node, std::uint32_t, std::uint64_t, std::uint64_t) {
    covered.push_back(node);
  });
  return covered;
}

// Adds each of the node's labels of category c (in the selection) to counts, along its label
// edges: top-k's plain way.
void NanocubeView::count_labels(const ResolvedSelection& r, std::size_t c, std::uint32_t node,
                                std::vector<std::uint64_t>& counts) const {
  leaves(r, 0, node, c, 0, [&](std::uint32_t series, std::uint32_t label) {
    counts[label] += series_count(series, r.b0, r.b1);
  });
}

}  // namespace kiln
