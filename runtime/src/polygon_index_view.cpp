// The polygon index view: the validating walk at open, and the queries (descend to the leaf
// holding the point, then decide each listed polygon by its wholly-inside mark or by the parity
// of its listed edges' crossings with the ray from the point towards +x).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "kiln/runtime/error.hpp"
#include "kiln/runtime/polygon_index.hpp"
#include "kiln/runtime/predicates2.hpp"
#include "polygon_index_records.hpp"
#include "predicates2_inline.hpp"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace kiln {

using format::Box2d;
using format::Double2;
using format::PolygonIndexEdge;
using format::PolygonIndexEntry;
using format::PolygonIndexNode;

PolygonIndexView::PolygonIndexView(const PolygonIndexParts& parts, const std::string& name)
    : parts_(parts) {
  validate(name);
  top_ = make_polygon_index_top_grid(parts_);
  if (!top_)
    throw BlobError("polygon index '" + name +
                    "': entries share edges, or its leaf records would outgrow 32-bit offsets");
  record_ = polygon_records::kernel(polygon_records::best_kernel());
}

namespace {

[[noreturn]] void fail(const std::string& name, const std::string& what) {
  throw BlobError("polygon index '" + name + "': " + what);
}

// Every leaf, reached or not (the leaf records built at open read them all): entries in range,
// and leaves own disjoint ranges, so the walks over leaves read each entry at most once.
void check_leaf_ranges(const PolygonIndexParts& p, const std::string& name) {
  std::uint64_t leaf_entries = 0;
  for (std::size_t i = 0; i < p.nodes.size(); ++i) {
    const PolygonIndexNode& n = p.nodes[i];
    if (!n.is_leaf()) continue;
    if (std::uint64_t(n.first) + n.count > p.entries.size())
      fail(name, "leaf " + std::to_string(i) + " has entries out of range");
    if ((leaf_entries += n.count) > p.entries.size()) fail(name, "leaves share entries");
  }
}

}  // namespace

// Each node reached once from the root, children stored after their parent, depth bounded;
// every leaf's entries, their polygons and edge ranges, and every edge's vertices in range.
void PolygonIndexView::validate(const std::string& name) const {
  const auto& p = parts_;
  if (p.nodes.empty()) fail(name, "has no nodes");
  if (p.layer.feature_polygons.empty() || p.layer.polygon_rings.empty())
    fail(name, "has no polygon layer");
  if (p.layer.polygon_count() > 0xFFFFFFFEu || p.layer.vertices.size() > 0xFFFFFFFFu)
    fail(name, "indexes a layer too large for 32-bit indices");
  if (p.nodes.size() > 0x7FFFFFFFu) fail(name, "has 2^31 nodes or more");
  std::vector<bool> reached(p.nodes.size());
  std::vector<std::pair<std::uint32_t, std::uint32_t>> stack{{0, 0}};  // node, depth
  reached[0] = true;
  check_leaf_ranges(p, name);
  while (!stack.empty()) {
    const auto [index, depth] = stack.back();
    stack.pop_back();
    const PolygonIndexNode& n = p.nodes[index];
    if (!n.is_leaf()) {
      if (n.first <= index || p.nodes.size() < 4 || n.first > p.nodes.size() - 4)
        fail(name, "node " + std::to_string(index) + " has children out of order or range");
      if (depth + 1 > format::kPolygonIndexMaxDepth)
        fail(name, "is deeper than " + std::to_string(format::kPolygonIndexMaxDepth));
      for (std::uint32_t c = n.first; c < n.first + 4; ++c) {
        if (reached[c]) fail(name, "node " + std::to_string(c) + " is reached twice");
        reached[c] = true;
        stack.emplace_back(c, depth + 1);
      }
      continue;
    }
    for (std::uint32_t i = n.first + 1; i < n.first + n.count; ++i)
      if (p.entries[i].polygon <= p.entries[i - 1].polygon)
        fail(name, "entry " + std::to_string(i) + " names a polygon out of order");
  }
  // Every entry, reached or not (kiln verify reads them all).
  for (std::size_t i = 0; i < p.entries.size(); ++i) {
    const PolygonIndexEntry& e = p.entries[i];
    if (e.polygon >= p.layer.polygon_count())
      fail(name, "entry " + std::to_string(i) + " names a polygon out of range");
    if (std::uint64_t(e.first_edge) + e.edges() > p.edges.size())
      fail(name, "entry " + std::to_string(i) + " has edges out of range");
  }
  const std::uint64_t vertices = p.layer.vertices.size();
  for (std::size_t i = 0; i < p.edges.size(); ++i)
    if (p.edges[i].a >= vertices || p.edges[i].b >= vertices)
      fail(name, "edge " + std::to_string(i) + " names a vertex out of range");
}

std::uint32_t PolygonIndexView::feature_of(std::uint32_t polygon) const {
  // Tabled at open: the feature f with feature_polygons[f] <= polygon < feature_polygons[f + 1].
  return polygon < top_->feature.size() ? top_->feature[polygon] : PolygonQueries::kNone;
}

// Edges in blocks of 64: first the box test of every edge of the block without a branch (a bit
// per edge meeting the segment's box; most edges of a cell miss it), then the exact test only
// for the few set bits, so the loop's branches do not depend on the data edge by edge.
bool PolygonIndexView::entry_contains(const PolygonIndexEntry& e, const Box2d& cell,
                                      const Double2& p, Cost* cost) const {
  if (e.wholly_inside()) return true;
  const auto vertices = parts_.layer.vertices;
  const Double2 c = format::quadtree_centre(cell);
  const Double2 lo{std::min(c.x, p.x), std::min(c.y, p.y)};
  const Double2 hi{std::max(c.x, p.x), std::max(c.y, p.y)};
  bool inside = e.centre_inside();
  const auto edges = parts_.edges.subspan(e.first_edge, e.edges());
  for (std::size_t i = 0; i < edges.size(); i += 64) {
    const std::size_t n = std::min<std::size_t>(64, edges.size() - i);
    std::uint64_t hits = 0;
    for (std::size_t j = 0; j < n; ++j) {
      const Double2& a = vertices[edges[i + j].a];
      const Double2& b = vertices[edges[i + j].b];
      const bool miss = (std::max(a.x, b.x) < lo.x) | (std::min(a.x, b.x) > hi.x) |
                        (std::max(a.y, b.y) < lo.y) | (std::min(a.y, b.y) > hi.y);
      hits |= std::uint64_t(!miss) << j;
    }
    for (; hits; hits &= hits - 1) {
      const PolygonIndexEdge& edge = edges[i + std::size_t(__builtin_ctzll(hits))];
      inside ^= detail::shifted_segment_crosses_unboxed(c, p, vertices[edge.a], vertices[edge.b]);
    }
  }
  if (cost) cost->tests += e.edges();
  return inside;
}

namespace {

// A column and a row among the table's fine split lines (level k + kFine).
struct Fine {
  std::uint32_t x, y;
};

// The fine column or row of v's uniform estimate, clamped to [0, last] (NaN: 0), for any v: for
// v in the bounds, within a rounding of the true one (within kEstimateSlack wherever
// PolygonIndexTopGrid::clear is used).
template <class G>
inline Fine estimate(const G& g, const Box2d& bounds, const Double2& p) {
  const double last = double(g.last);
#if defined(__SSE2__)
  // Both axes at once; maxpd answers its second operand, 0, where the first is NaN.
  __m128d e = _mm_mul_pd(_mm_sub_pd(_mm_loadu_pd(&p.x), _mm_loadu_pd(&bounds.min.x)),
                         _mm_loadu_pd(&g.scale.x));
  e = _mm_min_pd(_mm_max_pd(e, _mm_setzero_pd()), _mm_set1_pd(last));
  const __m128i i = _mm_cvttpd_epi32(e);
  return {std::uint32_t(_mm_cvtsi128_si32(i)),
          std::uint32_t(_mm_cvtsi128_si32(_mm_srli_si128(i, 4)))};
#else
  auto axis = [last](double v, double min, double scale) {
    double e = (v - min) * scale;
    e = e > 0 ? e : 0;
    return std::uint32_t(e < last ? e : last);
  };
  return {axis(p.x, bounds.min.x, g.scale.x), axis(p.y, bounds.min.y, g.scale.y)};
#endif
}

template <class G>
inline std::size_t table_cell(const G& g, Fine f) {
  constexpr std::uint32_t k = PolygonIndexTopGrid::kFine;
  return std::size_t(f.y >> k) << g.level | f.x >> k;
}

// Whether the table says p is in no polygon from its estimated column and row alone.
template <class G>
inline bool clear(const G& g, Fine estimate) {
  const std::size_t cell = table_cell(g, estimate);
  return g.clear[cell / 64] >> (cell % 64) & 1;
}

// The largest j <= last with lines[j] <= v, for v inside [lines.front(), lines.back()]: the
// column the descent reaches (it sends v >= a split line to the upper side), from the estimate
// j; the walks correct it (the split lines are non-decreasing, so they end).
[[gnu::noinline, gnu::cold]] std::uint32_t walk_column(const double* lines, double v,
                                                       std::uint32_t j, std::uint32_t last) {
  while (j > 0 && lines[j] > v) --j;
  while (j < last && lines[j + 1] <= v) ++j;
  return j;
}

inline std::uint32_t column(const double* lines, double v, std::uint32_t j, std::uint32_t last) {
  if ((lines[j] <= v) & (v < lines[j + 1])) [[likely]]
    return j;
  return walk_column(lines, v, j, last);
}

// p's fine column and row, from their estimates.
template <class G>
inline Fine fine(const G& g, const Double2& p, Fine estimate) {
  return {column(&g.xs[0], p.x, estimate.x, g.last), column(&g.ys[0], p.y, estimate.y, g.last)};
}

// Box2d::contains with one branch instead of four.
inline bool inside(const Box2d& b, const Double2& p) {
  return (p.x >= b.min.x) & (p.x <= b.max.x) & (p.y >= b.min.y) & (p.y <= b.max.y);
}

// Child bits of the kFine levels below a table cell, first level most significant, from the
// fine column's and row's low bits: bit i of x goes to bit 2i, of y to bit 2i + 1.
constexpr std::uint8_t kSpread[8] = {0, 1, 4, 5, 16, 17, 20, 21};
static_assert(PolygonIndexTopGrid::kFine == 3);

inline std::uint32_t answer_of(std::uint32_t code) {
  const std::uint32_t f = code & PolygonIndexTopGrid::kNoFeature;
  return f == PolygonIndexTopGrid::kNoFeature ? PolygonQueries::kNone : f;
}

inline bool is_branch(std::uint32_t code) {
  return (code & (PolygonIndexTopGrid::kAnswer | PolygonIndexTopGrid::kBranch)) ==
         PolygonIndexTopGrid::kBranch;
}

// The branch entry a point reaches below `box`: the d levels' child bits, first most significant.
inline std::uint32_t branch_entry(std::uint32_t code, Box2d& box, const Double2& p) {
  const std::uint32_t d = 1 + (code >> 28 & 3);
  std::uint32_t index = 0;
  for (std::uint32_t l = 0; l < d; ++l) {
    const std::uint32_t child = format::quadtree_child_of(box, p);
    box = format::quadtree_child_box(box, child);
    index = index << 2 | child;
  }
  return (code & PolygonIndexTopGrid::kOffset) + index;
}

// Branches below kFine levels, entered from the fine cell's box.
[[gnu::noinline, gnu::cold]] std::uint32_t deep_code(const PolygonIndexTopGrid& g,
                                                     std::uint32_t code, Fine f, const Double2& p) {
  Box2d box{{g.xs[f.x], g.ys[f.y]}, {g.xs[f.x + 1], g.ys[f.y + 1]}};
  do code = g.code[branch_entry(code, box, p)];
  while (is_branch(code));
  return code;
}

// The code of the leaf holding p (fine column and row `f`), from its table cell's: a branch's
// entry from f's low bits, then (below kFine levels) branches again, descending from the fine
// cell. (Reading the entry without a branch, a cell that is no branch reading itself again,
// measured slower.)
inline std::uint32_t leaf_code(const PolygonIndexTopGrid& g, Fine f, const Double2& p) {
  std::uint32_t code = g.code[table_cell(g, f)];
  if (!is_branch(code)) return code;
  const std::uint32_t d = 1 + (code >> 28 & 3);
  code = g.code[(code & PolygonIndexTopGrid::kOffset) +
                ((kSpread[f.x & 7] | kSpread[f.y & 7] << 1) >> 2 * (3 - d))];
  if (is_branch(code)) [[unlikely]]
    return deep_code(g, code, f, p);
  return code;
}

// The table's fields locate_many reads, copied into the call's frame: the record kernel is called
// through a pointer, after which the compiler must assume any heap word changed and would
// reload each vector's pointer and the table's sizes.
struct HotTable {
  const std::uint32_t* code;
  const std::uint64_t* clear;
  const double *xs, *ys;
  const std::uint64_t* records;
  std::uint32_t level, last;
  Double2 scale;
  explicit HotTable(const PolygonIndexTopGrid& g)
      : code(g.code.data()),
        clear(g.clear.data()),
        xs(g.xs.data()),
        ys(g.ys.data()),
        records(g.records.data()),
        level(g.level),
        last(g.last),
        scale(g.scale) {}
};

}  // namespace

// Calls visit(entry, cell) for each entry of the leaf holding p, in order, until it returns
// false. The descent runs from the root on the stored nodes (not the table's codes); `cost`
// counts the table lookup as one node and each level below the table's as one more.
template <class Visit>
void PolygonIndexView::visit_leaf(const Double2& p, Visit&& visit, Cost* cost) const {
  if (!parts_.bounds.contains(p)) return;
  Box2d box = parts_.bounds;
  const PolygonIndexNode* n = &parts_.nodes[0];
  if (cost) ++cost->nodes;
  for (std::uint32_t depth = 1; !n->is_leaf(); ++depth) {
    const std::uint32_t child = format::quadtree_child_of(box, p);
    box = format::quadtree_child_box(box, child);
    n = &parts_.nodes[n->first + child];
    if (cost && depth > top_->level) ++cost->nodes;
  }
  for (const PolygonIndexEntry& e : parts_.entries.subspan(n->first, n->count))
    if (!visit(e, box)) return;
}

namespace {

// locate past the clear bits, apart so that the clear path stays a few instructions: the
// bounds, the leaf's code through at most a branch or two, then its record.
[[gnu::noinline]] std::uint32_t locate_past_clear(const PolygonIndexTopGrid& g, const Box2d& bounds,
                                                  PolygonRecordKernel record, const Double2& p,
                                                  Fine e) {
  if (!inside(bounds, p)) return PolygonQueries::kNone;
  const std::uint32_t code = leaf_code(g, fine(g, p, e), p);
  if (code & PolygonIndexTopGrid::kAnswer) return answer_of(code);
  return record(&g.records[code], p);
}

}  // namespace

// The hot path: a bit per cell (32 KB at k = 9) settles most empty space from the estimates
// alone, before the bounds (a point outside them is in no polygon either); a cell answering
// alike for all its points ends at its code.
std::uint32_t PolygonIndexView::locate(const Double2& p) const {
  const PolygonIndexTopGrid& g = *top_;
  const Fine e = estimate(g, parts_.bounds, p);
  if (clear(g, e)) return PolygonQueries::kNone;
  return locate_past_clear(g, parts_.bounds, record_, p, e);
}

// A batch in groups of 16 points, software-pipelined over four stages: while group g computes
// its table cells, group g - 1 reads its codes, g - 2 its branch entries and g - 3 its leaf
// records, each stage prefetching what the next one reads, so a group's cache misses are served
// while three other groups work. Answers are locate's: the same steps on the same doubles.
void PolygonIndexView::locate_many(std::span<const Double2> points,
                                   std::span<std::uint32_t> out) const {
  constexpr std::size_t kGroup = 64, kStages = 4;
  struct Group {
    std::size_t size = 0;        // points still open
    std::uint32_t at[kGroup];    // their index in the batch
    Fine f[kGroup];              // fine column and row
    std::uint32_t code[kGroup];  // table cell, then code, then (stage 3) record
  };
  const std::size_t n = std::min(points.size(), out.size());
  const PolygonIndexTopGrid& grid = *top_;
  const HotTable g(grid);
  const Box2d bounds = parts_.bounds;
  const PolygonRecordKernel record = record_;
  Group ring[kStages];
  const std::size_t groups = (n + kGroup - 1) / kGroup;
  for (std::size_t step = 0; step < groups + kStages - 1; ++step) {
    // Stage 3: records (group step - 3).
    if (step >= 3 && step - 3 < groups) {
      const Group& r = ring[(step - 3) % kStages];
      for (std::size_t i = 0; i < r.size; ++i)
        out[r.at[i]] = r.code[i] & PolygonIndexTopGrid::kAnswer
                           ? answer_of(r.code[i])
                           : record(&g.records[r.code[i]], points[r.at[i]]);
    }
    // Stage 2: branch entries (group step - 2); deeper branches resolved on the spot.
    if (step >= 2 && step - 2 < groups) {
      Group& r = ring[(step - 2) % kStages];
      for (std::size_t i = 0; i < r.size; ++i) {
        std::uint32_t code = r.code[i];
        if (is_branch(code)) {
          code = g.code[code & PolygonIndexTopGrid::kOffset];
          if (is_branch(code)) {
            const Double2& p = points[r.at[i]];
            code = deep_code(grid, code, r.f[i], p);
          }
          r.code[i] = code;
        }
        if (!(code & PolygonIndexTopGrid::kAnswer)) {
          const char* record = reinterpret_cast<const char*>(&g.records[code]);
          __builtin_prefetch(record);
          __builtin_prefetch(record + 64);
          __builtin_prefetch(record + 128);
          __builtin_prefetch(record + 183);
        }
      }
    }
    // Stage 1: codes (group step - 1). A branch's code becomes the offset of its entry (flagged
    // as a branch still).
    if (step >= 1 && step - 1 < groups) {
      Group& r = ring[(step - 1) % kStages];
      std::size_t kept = 0;
      for (std::size_t i = 0; i < r.size; ++i) {
        std::uint32_t code = g.code[r.code[i]];
        if (is_branch(code)) {
          const std::uint32_t d = 1 + (code >> 28 & 3);
          const std::uint32_t entry =
              (code & PolygonIndexTopGrid::kOffset) +
              ((kSpread[r.f[i].x & 7] | kSpread[r.f[i].y & 7] << 1) >> 2 * (3 - d));
          __builtin_prefetch(&g.code[entry]);
          code = PolygonIndexTopGrid::kBranch | entry;
        } else if (code & PolygonIndexTopGrid::kAnswer) {
          out[r.at[i]] = answer_of(code);
          continue;
        } else {
          __builtin_prefetch(&g.records[code]);
        }
        r.at[kept] = r.at[i], r.f[kept] = r.f[i];
        r.code[kept++] = code;
      }
      r.size = kept;
    }
    // Stage 0: table cells (group step).
    if (step < groups) {
      Group& r = ring[step % kStages];
      r.size = 0;
      const std::size_t end = std::min(n, (step + 1) * kGroup);
      for (std::size_t k = step * kGroup; k < end; ++k) {
        const Double2& p = points[k];
        out[k] = PolygonQueries::kNone;
        const Fine e = estimate(g, bounds, p);
        if (clear(g, e) || !inside(bounds, p)) continue;
        const Fine f = fine(g, p, e);
        const std::size_t cell = table_cell(g, f);
        __builtin_prefetch(&g.code[cell]);
        r.at[r.size] = std::uint32_t(k), r.f[r.size] = f;
        r.code[r.size++] = std::uint32_t(cell);
      }
    }
  }
}

std::uint32_t PolygonIndexView::locate_counting(const Double2& p, Cost& cost) const {
  std::uint32_t found = PolygonQueries::kNone;
  visit_leaf(
      p,
      [&](const PolygonIndexEntry& e, const Box2d& cell) {
        if (!entry_contains(e, cell, p, &cost)) return true;
        found = feature_of(e.polygon);
        return false;
      },
      &cost);
  return found;
}

void PolygonIndexView::locate_all(const Double2& p, std::vector<std::uint32_t>& out) const {
  out.clear();
  visit_leaf(
      p,
      [&](const PolygonIndexEntry& e, const Box2d& cell) {
        if (entry_contains(e, cell, p, nullptr)) {
          const std::uint32_t f = feature_of(e.polygon);
          if (out.empty() || out.back() != f) out.push_back(f);  // entries ascend by polygon
        }
        return true;
      },
      nullptr);
}

}  // namespace kiln
