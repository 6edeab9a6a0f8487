// Topkube's top-k (Miranda, Lins, Klosowski & Silva 2018) over the nanocube: the stored
// rankings (all time, and per block of time bins), Fagin's threshold algorithm over them, and
// the deep checks kiln verify runs on them (docs/FORMAT.md §24.2-24.3).
#include <algorithm>
#include <functional>
#include <limits>
#include <optional>
#include <queue>
#include <stdexcept>
#include <utility>

#include "kiln/runtime/nanocube.hpp"

namespace kiln {

namespace {

// A ranked list the threshold walk reads: a time block's ranking or a node's all-time one, for
// walked node `slot` (the last slot: the counted nodes' exact counts).
// A node is walked when it selects at least 1/kLoose of the events its lists rank: looser bounds
// make the walk count more labels in every walked node than counting that node's own (measured
// on the 10 M table: 4 beats 16, 64 and no limit).
constexpr std::uint64_t kLoose = 4;

struct WalkList {
  std::span<const format::NanocubeRankEntry> entries;
  std::size_t slot;
  bool block;
};

// The lists ranking `node`'s labels over bins [lo, hi), from level i down to `finest`: the whole
// blocks inside (exact), then at the finest level the blocks holding the two ends no whole block
// covers (an upper bound for the ends). At most 2^stride blocks a side per level, since the
// level above took every whole block it could.
void block_cover(const NanocubeView& v, std::size_t c, std::uint32_t node, std::uint32_t finest,
                 std::uint32_t i, std::uint64_t lo, std::uint64_t hi, std::size_t slot,
                 std::vector<WalkList>& out) {
  if (lo >= hi) return;
  const std::uint64_t size = v.block_size(i), bins = v.grid().bin_count;
  auto end_of = [&](std::uint64_t b) { return std::min((b + 1) * size, bins); };
  auto push = [&](std::uint64_t b) { out.push_back({v.block_ranking(c, node, i, b), slot, true}); };
  const std::uint64_t first = (lo + size - 1) / size;
  std::uint64_t last = first;  // whole blocks first .. last - 1
  while (last * size < bins && end_of(last) <= hi) ++last;
  if (i == finest) {
    if (first == last) {  // under two blocks: the one or two holding the interval bound it
      for (std::uint64_t b = lo / size; b <= (hi - 1) / size; ++b) push(b);
      return;
    }
    if (lo < first * size) push(first - 1);
    for (std::uint64_t b = first; b < last; ++b) push(b);
    if (end_of(last - 1) < hi) push(last);
    return;
  }
  if (first == last) return block_cover(v, c, node, finest, i - 1, lo, hi, slot, out);
  block_cover(v, c, node, finest, i - 1, lo, first * size, slot, out);
  for (std::uint64_t b = first; b < last; ++b) push(b);
  block_cover(v, c, node, finest, i - 1, end_of(last - 1), hi, slot, out);
}

// Bins the lists of a node cover: [lo, hi) widened to the finest stored blocks' edges.
std::pair<std::uint64_t, std::uint64_t> covered_bins(const NanocubeView& v, std::uint32_t finest,
                                                     std::uint64_t lo, std::uint64_t hi) {
  const std::uint64_t bins = v.grid().bin_count;
  if (finest >= v.block_levels()) return {0, bins};
  const std::uint64_t size = v.block_size(finest);
  return {lo / size * size, std::min((hi + size - 1) / size * size, bins)};
}

ResolvedSelection unfiltered(std::size_t categories, std::uint64_t b0, std::uint64_t b1) {
  ResolvedSelection r;
  r.allowed.resize(categories);
  r.b0 = std::int64_t(b0), r.b1 = std::int64_t(b1);
  return r;
}

// Fagin's threshold algorithm over the lists, read depth by depth. `exact(label)` counts a label
// met over the whole selection and lowers left[slot] by its count under each slot (nullopt: the
// walk is over budget). A label not met yet has in each slot at most the sum of the slot's lists'
// counts at the next depth (a list is sorted and ranks a superset of the slot's selected events),
// and at most what is left of the slot; the walk stops once k labels count strictly more than the
// sum over slots, so ties (broken by label) are never cut. Returns false when over budget.
bool threshold_walk(std::span<const WalkList> lists, std::span<std::uint64_t> left, std::size_t k,
                    std::span<const char> allowed,
                    const std::function<std::optional<std::uint64_t>(std::uint32_t)>& exact,
                    std::vector<std::pair<std::uint32_t, std::uint64_t>>& hits) {
  std::size_t deepest = 0;
  for (const WalkList& l : lists) deepest = std::max(deepest, l.entries.size());
  std::vector<char> met;
  std::vector<std::uint64_t> next(left.size());
  std::priority_queue<std::uint64_t, std::vector<std::uint64_t>, std::greater<>> best;  // k largest
  for (std::size_t depth = 0; depth < deepest; ++depth) {
    for (const WalkList& l : lists) {
      if (depth >= l.entries.size()) continue;
      const std::uint32_t label = l.entries[depth].label;
      if (label >= met.size()) met.resize(label + 1, 0);
      if (std::exchange(met[label], 1) || (!allowed.empty() && !allowed[label])) continue;
      const auto n = exact(label);
      if (!n) return false;
      if (*n == 0) continue;
      hits.emplace_back(label, *n);
      best.push(*n);
      if (best.size() > k) best.pop();
    }
    std::fill(next.begin(), next.end(), 0);
    for (const WalkList& l : lists)
      if (depth + 1 < l.entries.size()) next[l.slot] += l.entries[depth + 1].count;
    std::uint64_t bound = 0;
    for (std::size_t j = 0; j < next.size(); ++j) bound += std::min(next[j], left[j]);
    if (bound == 0 || (best.size() == k && best.top() > bound)) break;
  }
  return true;
}

// Non-zero counts as a ranking (counts down, ties by label).
std::vector<format::NanocubeRankEntry> ranked_counts(std::span<const std::uint64_t> counts) {
  std::vector<format::NanocubeRankEntry> out;
  for (std::uint32_t i = 0; i < counts.size(); ++i)
    if (counts[i] != 0) out.push_back({i, std::uint32_t(counts[i])});
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
    return a.count != b.count ? a.count > b.count : a.label < b.label;
  });
  return out;
}

}  // namespace

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

std::uint32_t NanocubeView::block_finest(std::size_t c, std::uint32_t node) const {
  return block_levels_ == 0 ? 0 : block_index_[c * dimension_nodes_[1] + node].finest;
}

std::span<const format::NanocubeRankEntry> NanocubeView::block_ranking(std::size_t c,
                                                                       std::uint32_t node,
                                                                       std::uint32_t level,
                                                                       std::uint64_t block) const {
  if (level >= block_levels_) return {};
  const format::NanocubeBlockIndex& x = block_index_[c * dimension_nodes_[1] + node];
  if (x.finest > level) return {};
  const std::uint64_t blocks = level_start_[level + 1] - level_start_[level];
  if (block >= blocks) return {};
  const format::NanocubeRankList& l =
      block_lists_[x.first_list + level_start_[level] - level_start_[x.finest] + block];
  return block_entries_.subspan(l.first, l.count);
}

bool NanocubeView::block_rankings_consistent() const {
  ResolvedSelection block = unfiltered(table_.categories.size(), 0, 0);
  for (std::size_t c = 0; c < table_.categories.size(); ++c)
    for (std::uint32_t node = 0; node < dimension_nodes_[1]; ++node)
      for (std::uint32_t i = block_finest(c, node); i < block_levels_; ++i)
        for (std::uint64_t b = 0; b < level_start_[i + 1] - level_start_[i]; ++b) {
          const std::uint64_t size = block_size(i);
          block.b0 = std::int64_t(b * size);
          block.b1 = std::int64_t(std::min<std::uint64_t>((b + 1) * size, grid_.bin_count));
          std::uint64_t total = 0;
          for (const format::NanocubeRankEntry& e : block_ranking(c, node, i, b)) {
            if (label_count(block, node, c, e.label) != e.count) return false;
            total += e.count;
          }
          if (total != node_count(block, node)) return false;
        }
  return true;
}

std::vector<EventLabelCount> NanocubeView::topk(const EventSelection& s, std::string_view by,
                                                std::size_t k) const {
  TopkTrace trace;
  return topk_traced(s, by, k, trace);
}

std::vector<EventLabelCount> NanocubeView::topk_counting(const EventSelection& s,
                                                         std::string_view by, std::size_t k,
                                                         std::size_t& counted) const {
  TopkTrace trace;
  auto out = topk_traced(s, by, k, trace);
  counted = trace.labels_counted;
  return out;
}

// With no time limit and no filter on another category, the covered nodes' all-time rankings
// ARE the counts: added label by label. Otherwise the threshold walk (threshold_topk).
std::vector<EventLabelCount> NanocubeView::topk_traced(const EventSelection& s, std::string_view by,
                                                       std::size_t k, TopkTrace& trace) const {
  trace = {};
  const auto c = table_.category(by);
  if (!c) throw std::invalid_argument("no category '" + std::string(by) + "' in the event table");
  const ResolvedSelection r = resolve_event_selection(s, table_, grid_);
  if (r.empty || k == 0) return {};
  const std::vector<std::uint32_t> covered = covered_nodes(r);
  bool exact = r.b0 <= 0 && r.b1 >= std::int64_t(grid_.bin_count);
  for (std::size_t other = 0; other < r.allowed.size(); ++other)
    exact = exact && (other == *c || r.allowed[other].empty());
  if (!exact) return threshold_topk(r, *c, k, covered, trace);
  trace.path = TopkTrace::Path::kRankings;
  std::vector<std::uint64_t> counts(table_.categories[*c].label_count, 0);
  const std::vector<char>& allowed = r.allowed[*c];
  for (const std::uint32_t node : covered)
    for (const format::NanocubeRankEntry& e : ranking(*c, node))
      if (allowed.empty() || allowed[e.label]) counts[e.label] += e.count;
  return labels_by_count(counts, *c, k);
}

std::vector<EventLabelCount> NanocubeView::labels_by_count(std::span<const std::uint64_t> counts,
                                                           std::size_t c, std::size_t k) const {
  std::vector<EventLabelCount> all;
  for (std::uint32_t i = 0; i < counts.size(); ++i)
    if (counts[i] != 0) all.push_back({std::string(table_.label(c, i)), counts[i]});
  return top_labels(std::move(all), k);
}

// The covered nodes split two ways. A node with few labels (at most 2k + 2), or whose stored
// rankings cover far more events than it selects (a filter on another category, a short interval
// inside a big block), has its labels counted: cheap, or what the walk would cost anyway. The
// others are walked: their rankings for the interval (whole time blocks, the blocks holding the
// ends, or the all-time ranking where no block is stored) feed the threshold algorithm, next to
// one exact list of the counted nodes' counts. Past as many exact counts as counting the walked
// nodes would read, the walk gives up and counts them.
std::vector<EventLabelCount> NanocubeView::threshold_topk(const ResolvedSelection& r, std::size_t c,
                                                          std::size_t k,
                                                          std::span<const std::uint32_t> covered,
                                                          TopkTrace& trace) const {
  const std::uint64_t bins = grid_.bin_count;
  const auto lo = std::uint64_t(std::clamp<std::int64_t>(r.b0, 0, std::int64_t(bins)));
  const auto hi = std::uint64_t(std::clamp<std::int64_t>(r.b1, 0, std::int64_t(bins)));
  if (lo >= hi) return {};
  std::vector<std::uint64_t> counts(table_.categories[c].label_count, 0), left;
  std::vector<std::uint32_t> walked;
  std::vector<WalkList> lists;
  std::size_t walk_cost = 0;  // labels that counting the walked nodes would read
  ResolvedSelection spanned = unfiltered(table_.categories.size(), 0, 0);
  for (const std::uint32_t node : covered) {
    const std::size_t labels = ranking(c, node).size();
    const std::uint64_t selected = labels <= 2 * k + 2 ? 0 : node_count(r, node);
    if (selected > 0) {
      const std::uint32_t finest = block_finest(c, node);
      const auto [u0, u1] = covered_bins(*this, finest, lo, hi);
      spanned.b0 = std::int64_t(u0), spanned.b1 = std::int64_t(u1);
      if (kLoose * selected >= node_count(spanned, node)) {
        if (finest < block_levels_ && (lo > 0 || hi < bins))
          block_cover(*this, c, node, finest, block_levels_ - 1, lo, hi, walked.size(), lists);
        else
          lists.push_back({ranking(c, node), walked.size(), false});
        walked.push_back(node), left.push_back(selected), walk_cost += labels;
        continue;
      }
    } else if (labels > 2 * k + 2) {
      continue;  // nothing selected under it
    }
    count_labels(r, c, node, counts), ++trace.counted_nodes, trace.counted_labels += labels;
  }
  trace.walked_nodes = walked.size();
  trace.path = walked.empty() ? TopkTrace::Path::kCounted : TopkTrace::Path::kThreshold;
  for (const WalkList& l : lists) trace.block_lists += l.block;
  const std::vector<format::NanocubeRankEntry> counted = ranked_counts(counts);
  lists.push_back({counted, walked.size(), false});
  left.push_back(std::numeric_limits<std::uint64_t>::max());
  auto exact = [&](std::uint32_t label) -> std::optional<std::uint64_t> {
    if ((trace.labels_counted + 1) * walked.size() > walk_cost) return std::nullopt;
    ++trace.labels_counted;
    std::uint64_t n = counts[label];
    for (std::size_t j = 0; j < walked.size(); ++j) {
      const std::uint64_t in_node = label_count(r, walked[j], c, label);
      left[j] -= std::min(left[j], in_node);
      n += in_node;
    }
    return n;
  };
  std::vector<std::pair<std::uint32_t, std::uint64_t>> hits;
  if (walked.empty() || !threshold_walk(lists, left, k, r.allowed[c], exact, hits)) {
    for (const std::uint32_t node : walked) count_labels(r, c, node, counts);
    if (!walked.empty()) trace.path = TopkTrace::Path::kCounted;
    return labels_by_count(counts, c, k);
  }
  std::vector<EventLabelCount> out;
  for (const auto& [label, n] : hits) out.push_back({std::string(table_.label(c, label)), n});
  return top_labels(std::move(out), k);
}

}  // namespace kiln
