// The polygon index's top-level table (PolygonIndexTopGrid): derived at open from the nodes the
// view has validated, so it holds no bytes of its own to check, and used by every point query to
// skip the descent with one lookup, then at most a branch entry, then one leaf record.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>

#include "kiln/runtime/polygon_index.hpp"
#include "polygon_index_records.hpp"
#include "predicates2_inline.hpp"

namespace kiln {

using format::Box2d;
using format::Double2;
using Grid = PolygonIndexTopGrid;

namespace {

// The split lines of level `level` along one axis, each level's midpoints computed exactly as
// quadtree_child_box computes them: 0.5 * lo + 0.5 * hi.
std::vector<double> split_lines(double lo, double hi, std::uint32_t level) {
  std::vector<double> s{lo, hi};
  for (std::uint32_t l = 0; l < level; ++l) {
    std::vector<double> next(2 * s.size() - 1);
    for (std::size_t i = 0; i + 1 < s.size(); ++i) {
      next[2 * i] = s[i];
      next[2 * i + 1] = 0.5 * s[i] + 0.5 * s[i + 1];
    }
    next.back() = s.back();
    s = std::move(next);
  }
  return s;
}

// One edge of a record group while it is built: its endpoints oriented so that the leaf's
// centre lies to its left, and the group's polygons it bounds.
struct GroupEdge {
  Double2 a, b;
  std::uint32_t mask;
  double coordinate(std::size_t axis) const {
    return axis == 0 ? a.x : axis == 1 ? a.y : axis == 2 ? b.x : b.y;
  }
  // Bit patterns, for a total order and equality (NaN coordinates of a forged layer included).
  std::array<std::uint64_t, 4> key() const {
    return {std::bit_cast<std::uint64_t>(a.x), std::bit_cast<std::uint64_t>(a.y),
            std::bit_cast<std::uint64_t>(b.x), std::bit_cast<std::uint64_t>(b.y)};
  }
  bool same(const GroupEdge& o) const {
    return std::bit_cast<std::uint64_t>(a.x) == std::bit_cast<std::uint64_t>(o.a.x) &&
           std::bit_cast<std::uint64_t>(a.y) == std::bit_cast<std::uint64_t>(o.a.y) &&
           std::bit_cast<std::uint64_t>(b.x) == std::bit_cast<std::uint64_t>(o.b.x) &&
           std::bit_cast<std::uint64_t>(b.y) == std::bit_cast<std::uint64_t>(o.b.y);
  }
};

class Builder {
 public:
  Builder(const PolygonIndexParts& parts, Grid& g) : parts_(parts), g_(g) {}

  // Subtree depths of the nodes the root reaches (the validation checked only those: a node
  // nothing reaches may name children anywhere), children after their parent in the walk's
  // order; then the table's codes.
  bool build() {
    std::vector<std::uint32_t> order{0};
    for (std::size_t i = 0; i < order.size(); ++i)
      if (const format::PolygonIndexNode& n = parts_.nodes[order[i]]; !n.is_leaf())
        for (std::uint32_t c = 0; c < 4; ++c) order.push_back(n.first + c);
    depth_.assign(parts_.nodes.size(), 0);
    std::size_t words = 0, refs = 0;
    for (std::size_t i = order.size(); i-- > 0;) {
      const format::PolygonIndexNode& n = parts_.nodes[order[i]];
      if (n.is_leaf()) {
        // At most this many record words (before edges shared by polygons are merged).
        for (std::size_t first = 0; first < n.count; first += Grid::kGroupPolygons) {
          const std::size_t m = std::min<std::size_t>(Grid::kGroupPolygons, n.count - first);
          std::size_t edges = 0;
          for (const auto& e : parts_.entries.subspan(n.first + first, m)) edges += e.edges();
          refs += edges;
          words += polygon_records::kHeadWords + (edges + 3) / 4 * polygon_records::kBlockWords +
                   (m + 2) / 2;
        }
        continue;
      }
      std::uint8_t d = 0;
      for (std::uint32_t c = 0; c < 4; ++c) d = std::max(d, depth_[n.first + c]);
      depth_[order[i]] = std::uint8_t(d + 1);
    }
    // Reserved, not touched: growing by doubling would copy (and fault in) several times more.
    if (refs <= parts_.edges.size()) g_.records.reserve(words);
    fill(0, parts_.bounds, 0, 0, 0);
    return ok_;
  }

 private:
  // Writes the code of `node` (at depth `depth`, covering table cells [x0, x0 + size) x [y0,
  // y0 + size), size = 2^(k - depth)) into its cells, or recurses into its children above k.
  void fill(std::uint32_t node, const Box2d& box, std::uint32_t depth, std::uint32_t x0,
            std::uint32_t y0) {
    const std::uint32_t size = 1u << (g_.level - depth), side = 1u << g_.level;
    const format::PolygonIndexNode& n = parts_.nodes[node];
    if (n.is_leaf() || depth == g_.level) {
      const std::uint32_t code = code_of(node, box);
      for (std::uint32_t y = y0; y < y0 + size; ++y)
        std::fill_n(g_.code.begin() + std::ptrdiff_t(std::size_t(y) * side + x0), size, code);
      return;
    }
    const std::uint32_t half = size / 2;
    for (std::uint32_t c = 0; c < 4; ++c)
      fill(n.first + c, format::quadtree_child_box(box, c), depth + 1, x0 + (c & 1u ? half : 0),
           y0 + (c & 2u ? half : 0));
  }

  // The code a query reaching `node` (cell `box`) reads: a leaf's answer or record, else a new
  // branch over the next d = min(kFine, subtree depth) levels.
  std::uint32_t code_of(std::uint32_t node, const Box2d& box) {
    const format::PolygonIndexNode& n = parts_.nodes[node];
    if (n.is_leaf()) return leaf_code(n, box);
    const std::uint32_t d = std::min<std::uint32_t>(Grid::kFine, depth_[node]);
    const std::size_t at = g_.code.size();
    if (at + (std::size_t(1) << 2 * d) > Grid::kOffset + 1) return fail();
    g_.code.resize(at + (std::size_t(1) << 2 * d));
    fill_branch(node, box, d, at);
    return Grid::kBranch | (d - 1) << 28 | std::uint32_t(at);
  }

  // Entries at..at + 4^d of a branch: the codes of the cells `d` levels below `node`, child
  // bits interleaved, the first level's most significant; a leaf above them fills all of its.
  void fill_branch(std::uint32_t node, const Box2d& box, std::uint32_t d, std::size_t at) {
    const format::PolygonIndexNode& n = parts_.nodes[node];
    if (n.is_leaf() || d == 0) {
      const std::uint32_t code = code_of(node, box);
      std::fill_n(g_.code.begin() + std::ptrdiff_t(at), std::size_t(1) << 2 * d, code);
      return;
    }
    for (std::uint32_t c = 0; c < 4; ++c)
      fill_branch(n.first + c, format::quadtree_child_box(box, c), d - 1,
                  at + (std::size_t(c) << 2 * (d - 1)));
  }

  std::uint32_t fail() {
    ok_ = false;
    return Grid::kAnswer | Grid::kNoFeature;
  }

  // A leaf answering every point alike (no entry: none; a first entry wholly inside: its
  // feature, the lowest holding any point as entries ascend by polygon) is coded as that
  // answer; else its record is appended, groups of at most 31 polygons.
  std::uint32_t leaf_code(const format::PolygonIndexNode& n, const Box2d& box) {
    const auto entries = parts_.entries.subspan(n.first, n.count);
    if (entries.empty()) return Grid::kAnswer | Grid::kNoFeature;
    if (entries[0].wholly_inside()) {
      const std::uint32_t f = feature(entries[0].polygon);
      if (f < Grid::kNoFeature) return Grid::kAnswer | f;
    }
    const std::size_t at = g_.records.size();
    if (at > Grid::kRecordOffset) return fail();
    const Double2 c = format::quadtree_centre(box);
    for (std::size_t first = 0; first < entries.size(); first += Grid::kGroupPolygons) {
      const auto group = entries.subspan(
          first, std::min<std::size_t>(Grid::kGroupPolygons, entries.size() - first));
      if (!append_group(group, c, first + group.size() < entries.size())) return fail();
    }
    return std::uint32_t(at);
  }

  bool append_group(std::span<const format::PolygonIndexEntry> group, const Double2& c, bool more) {
    const auto v = parts_.layer.vertices;
    std::uint32_t centre = more ? 0x80000000u : 0;
    edges_.clear();
    for (std::size_t j = 0; j < group.size(); ++j) {
      const format::PolygonIndexEntry& e = group[j];
      const std::uint32_t bit = 1u << j;
      if (e.wholly_inside() || e.centre_inside()) centre |= bit;
      if ((edge_refs_ += e.edges()) > parts_.edges.size()) return false;  // shared ranges
      for (const format::PolygonIndexEdge& edge : parts_.edges.subspan(e.first_edge, e.edges())) {
        Double2 a = v[edge.a], b = v[edge.b];
        // The crossing test is symmetric in a and b; an edge with the centre on its line under
        // the shift has a == b and never crosses.
        const int side = detail::side_of_shifted_point(a, b, c);
        if (side == 0) continue;
        if (side < 0) std::swap(a, b);
        edges_.push_back({a, b, bit});
      }
    }
    // The same edge twice (neighbours' shared borders; a spike's two sides in one polygon):
    // once, with the polygons' bits xored (a polygon's own pair cancels, as its crossings do).
    // Few edges (nearly every leaf): pairwise, in order of first appearance; else sorted.
    std::size_t kept = 0;
    if (edges_.size() <= 32) {
      for (std::size_t i = 0; i < edges_.size(); ++i) {
        std::size_t j = 0;
        while (j < kept && !edges_[j].same(edges_[i])) ++j;
        if (j < kept)
          edges_[j].mask ^= edges_[i].mask;
        else
          edges_[kept++] = edges_[i];
      }
    } else {
      std::sort(edges_.begin(), edges_.end(),
                [](const GroupEdge& x, const GroupEdge& y) { return x.key() < y.key(); });
      for (std::size_t i = 0; i < edges_.size();) {
        GroupEdge merged = edges_[i];
        while (++i < edges_.size() && edges_[i].same(merged)) merged.mask ^= edges_[i].mask;
        edges_[kept++] = merged;
      }
    }
    edges_.resize(kept);
    std::erase_if(edges_, [](const GroupEdge& e) { return e.mask == 0; });
    // Blocks of four edges, a coordinate at a time, then the four masks; the last block padded
    // with copies of its first edge under an empty mask. Then the polygon count and features.
    const std::size_t blocks = (edges_.size() + 3) / 4;
    auto& r = g_.records;
    const std::size_t at = r.size();
    r.resize(at + polygon_records::kHeadWords + blocks * polygon_records::kBlockWords +
             (group.size() + 2) / 2);
    auto* out = reinterpret_cast<unsigned char*>(r.data() + at);
    auto put = [&out](auto value) {
      std::memcpy(out, &value, sizeof value);
      out += sizeof value;
    };
    put(std::uint32_t(blocks));
    put(centre);
    put(c.x);
    put(c.y);
    for (std::size_t k = 0; k < blocks; ++k) {
      const GroupEdge* block[4];
      for (std::size_t l = 0; l < 4; ++l)
        block[l] = &edges_[4 * k + l < edges_.size() ? 4 * k + l : 4 * k];
      for (std::size_t axis = 0; axis < 4; ++axis)
        for (const GroupEdge* e : block) put(e->coordinate(axis));
      for (std::size_t l = 0; l < 4; ++l) {
        const GroupEdge& e = *block[l];
        const std::uint32_t mask = 4 * k + l < edges_.size() ? e.mask : 0;
        // The shifted side of a point on the edge's line: right when the edge points up, or
        // along -x when horizontal (detail::side_of_shifted_point).
        const bool right = e.b.y != e.a.y ? e.b.y > e.a.y : !(e.b.x > e.a.x);
        put(mask | (right ? 0x80000000u : 0));
      }
    }
    put(std::uint32_t(group.size()));
    for (const format::PolygonIndexEntry& e : group) put(feature(e.polygon));
    return r.size() <= std::size_t(Grid::kRecordOffset) + 1;
  }

  std::uint32_t feature(std::uint32_t polygon) const {
    return polygon < g_.feature.size() ? g_.feature[polygon] : PolygonQueries::kNone;
  }

  const PolygonIndexParts& parts_;
  Grid& g_;
  std::vector<std::uint8_t> depth_;  // per node: its subtree's depth (at most 30, validated)
  std::vector<GroupEdge> edges_;
  std::uint64_t edge_refs_ = 0;
  bool ok_ = true;
};

// Whether the uniform estimate (v - min) * scale of every split line lies within kEstimateSlack
// of its index. The estimate grows with v (monotone rounding), so then the estimate of any v
// in [lines[j], lines[j + 1]) lies in [j - slack, j + 1 + slack]: its floor is within
// slack + 1 <= 2^kFine - 1 fine columns of j, and its table cell within one of the true one.
bool estimates_hold(const std::vector<double>& lines, double min, double scale) {
  for (std::size_t j = 0; j < lines.size(); ++j) {
    const double e = (lines[j] - min) * scale;
    if (!(e >= double(j) - Grid::kEstimateSlack && e <= double(j) + Grid::kEstimateSlack))
      return false;
  }
  return true;
}

}  // namespace

std::shared_ptr<const PolygonIndexTopGrid> make_polygon_index_top_grid(
    const PolygonIndexParts& parts) {
  auto g = std::make_shared<PolygonIndexTopGrid>();
  // 4^k cells for at most about 16 cells per node, and k <= 9 (1 MB of codes): deeper tables
  // cost more cache misses than the levels they skip (docs/BENCHMARKS.md).
  while (g->level < 9 && (std::uint64_t(4) << (2 * g->level)) <= 16 * parts.nodes.size())
    ++g->level;
  const std::uint32_t fine = g->level + Grid::kFine;
  g->xs = split_lines(parts.bounds.min.x, parts.bounds.max.x, fine);
  g->ys = split_lines(parts.bounds.min.y, parts.bounds.max.y, fine);
  const std::size_t cells = std::size_t(1) << (2 * g->level);
  const Box2d& b = parts.bounds;
  // A degenerate or forged side gives scale 0 (the lookup then walks from column 0).
  auto scale = [&](double side) {
    const double s = double(1u << fine) / side;
    return std::isfinite(s) && s > 0 ? s : 0.0;
  };
  g->scale = {scale(b.max.x - b.min.x), scale(b.max.y - b.min.y)};
  const auto offsets = parts.layer.feature_polygons;
  // Bounded by the table's size too: a view made from raw parts has no Blob::open checks.
  g->feature.assign(parts.layer.polygon_count(), PolygonQueries::kNone);
  for (std::size_t f = 0; f + 1 < offsets.size(); ++f)
    for (std::uint64_t q = offsets[f];
         q < std::min<std::uint64_t>(offsets[f + 1], g->feature.size()); ++q)
      g->feature[q] = std::uint32_t(f);
  g->code.resize(cells);
  if (!Builder(parts, *g).build()) return nullptr;
  g->last = (1u << fine) - 1;
  g->clear.assign((cells + 63) / 64, 0);
  if (estimates_hold(g->xs, b.min.x, g->scale.x) && estimates_hold(g->ys, b.min.y, g->scale.y)) {
    // Each row's empty cells as bits, the bits past the last column set (outside is empty); then
    // those whose row neighbours are empty too, then those whose rows above and below are too.
    const std::size_t side = std::size_t(1) << g->level, words = (side + 63) / 64;
    std::vector<std::uint64_t> rows(words * side), across(words * side);
    for (std::size_t y = 0; y < side; ++y) {
      std::uint64_t* row = &rows[y * words];
      if (side < 64) row[0] = ~std::uint64_t(0) << side;
      for (std::size_t x = 0; x < side; ++x)
        if (g->code[y * side + x] == (Grid::kAnswer | Grid::kNoFeature))
          row[x / 64] |= std::uint64_t(1) << (x % 64);
      for (std::size_t w = 0; w < words; ++w) {
        const std::uint64_t left = w > 0 ? row[w - 1] >> 63 : 1;
        const std::uint64_t right = w + 1 < words ? row[w + 1] << 63 : std::uint64_t(1) << 63;
        across[y * words + w] = row[w] & (row[w] << 1 | left) & (row[w] >> 1 | right);
      }
    }
    for (std::size_t y = 0; y < side; ++y)
      for (std::size_t w = 0; w < words; ++w) {
        const std::size_t at = y * words + w;
        const std::uint64_t up = y + 1 < side ? across[at + words] : ~std::uint64_t(0);
        const std::uint64_t down = y > 0 ? across[at - words] : ~std::uint64_t(0);
        const std::uint64_t bits = across[at] & up & down;
        if (side >= 64)  // rows of whole words, as the clear bits are
          g->clear[at] = bits;
        else  // several rows per word, none across two
          g->clear[y * side / 64] |= (bits & ((std::uint64_t(1) << side) - 1)) << (y * side % 64);
      }
  }
  return g;
}

}  // namespace kiln
