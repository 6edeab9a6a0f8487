// SAH-driven collapse of the binary BVH into 4- or 8-wide nodes with packet leaves: the dynamic
// programme of Ylitie, Karras, Laine (2017) with leaves priced per packet, or a greedy expansion.
#include "kiln/compiler/bvh_collapse.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <tuple>
#include <type_traits>

#include "huge_pages.hpp"
#include "kiln/formats/vector.hpp"
#include "kiln/runtime/parallel.hpp"

namespace kiln {

namespace {

float half_area(const format::BvhNode& n) {
  const float dx = n.max[0] - n.min[0], dy = n.max[1] - n.min[1], dz = n.max[2] - n.min[2];
  return dx * dy + dy * dz + dz * dx;
}

// One axis of a quantised node: origin and exponent such that origin + 255 x 2^e reaches every
// child's max, then per child the largest byte whose plane is <= min and the smallest whose plane
// is >= max, checked with the traversal's own float arithmetic.
template <int W>
void quantize_axis(const format::BvhWideNode<W>& in, int a, format::BvhQuantizedNode<W>& out) {
  float lo = std::numeric_limits<float>::infinity(), hi = -lo;
  for (int k = 0; k < W; ++k)
    if (in.bounds[a][0][k] <= in.bounds[a][1][k])
      lo = std::min(lo, in.bounds[a][0][k]), hi = std::max(hi, in.bounds[a][1][k]);
  const double extent = double(hi) - double(lo);
  int e = extent > 0 ? std::max(-126, int(std::ceil(std::log2(extent / 255.0)))) : -126;
  auto plane = [&](int q) { return lo + float(q) * format::bvh_quantized_scale(std::int8_t(e)); };
  while (e < 127 && plane(255) < hi) ++e;
  if (!(plane(255) >= hi)) throw std::invalid_argument("BVH coordinates too large to quantise");
  out.origin[a] = lo;
  out.exponent[a] = std::int8_t(e);
  const double scale = std::ldexp(1.0, e);
  for (int k = 0; k < W; ++k) {
    if (!(in.bounds[a][0][k] <= in.bounds[a][1][k])) {  // empty slot: inverted
      out.q[a][0][k] = 255, out.q[a][1][k] = 0;
      continue;
    }
    int qlo = int(std::clamp(std::floor((double(in.bounds[a][0][k]) - lo) / scale), 0.0, 255.0));
    int qhi = int(std::clamp(std::ceil((double(in.bounds[a][1][k]) - lo) / scale), 0.0, 255.0));
    while (qlo > 0 && plane(qlo) > in.bounds[a][0][k]) --qlo;
    while (qhi < 255 && plane(qhi) < in.bounds[a][1][k]) ++qhi;
    out.q[a][0][k] = std::uint8_t(qlo), out.q[a][1][k] = std::uint8_t(qhi);
  }
}

template <int W>
format::BvhQuantizedNode<W> quantize(const format::BvhWideNode<W>& in) {
  format::BvhQuantizedNode<W> out{};
  for (int a = 0; a < 3; ++a) quantize_axis(in, a, out);
  for (int k = 0; k < W; ++k) out.child[k] = in.child[k], out.packets[k] = in.packets[k];
  return out;
}

// The packets that `count` references fill.
constexpr std::uint32_t packets_of(std::uint32_t count) {
  return (count + format::kBvhPacketSize - 1) / format::kBvhPacketSize;
}

// A wide node's children (binary node indices), at most W, the first reference (in leaf order)
// of each one's subtree and one past its last binary node (pre-order), found on the way down
// instead of by walks to its first and last leaves.
template <int W>
struct Slots {
  std::uint32_t node[W], first[W], past[W];
  int size = 0;
  void push(std::uint32_t i, std::uint32_t f, std::uint32_t p) {
    node[size] = i, first[size] = f, past[size] = p, ++size;
  }
};

// What one writer of the arena counts, and its scratch list. A cache line (or more) of its own:
// writers on different threads update their tallies for every node.
struct alignas(64) WriteTally {
  std::uint64_t node_count = 0, leaf_count = 0, packet_count = 0, lanes_used = 0;
  std::uint32_t max_depth = 0;
  std::vector<std::uint32_t> scratch;
  // A wide node's leaf slots: their distinct references one after another, each slot's first
  // in `begin` (W + 1 entries), and the references' triangles and corners, loaded apart.
  // (Uninitialised: resizing up between nodes does not zero what is written next.)
  std::vector<std::uint32_t> leaf_refs;
  std::uint32_t begin[17];  // W + 1 at most (W <= 16)
  UninitializedVector<format::Triangle> triangles;
  UninitializedVector<format::RayTriangle> corners;
  // The references whose triangles, and those whose positions, were last prefetched.
  // (Triangles: the last two subtrees', the one being written and the next sibling's.)
  std::uint32_t triangles_from[2] = {}, triangles_to[2] = {}, positions_from = 0, positions_to = 0;
  int triangles_oldest = 0;
  void add(const WriteTally& o) {
    node_count += o.node_count, leaf_count += o.leaf_count, packet_count += o.packet_count;
    lanes_used += o.lanes_used, max_depth = std::max(max_depth, o.max_depth);
  }
};

// Subtrees written apart (in parallel) below the top levels, in arena order: each one's size,
// counted first, reserves its place while the top levels are written; its writer fills it.
struct TopLevels {
  struct Subtree {
    std::uint32_t node, first, past;  // the binary node, its first reference, its subtree's end
    std::size_t bytes = 0, leaf_lines = 0, at = 0;
    std::uint32_t depth = 0;
  };
  std::vector<Subtree> subtrees;
  std::size_t next = 0;  // the next one `write` meets
  bool has(std::uint32_t node) const {
    return next < subtrees.size() && subtrees[next].node == node;
  }
  // The next one, placed (place_top) at `at`.
  const Subtree& take(std::size_t at) {
    const Subtree& s = subtrees[next++];
    if (s.at != at) throw std::logic_error("collapse_bvh: a subtree written out of its place");
    return s;
  }
};

// What the collapse keeps per binary node, in one record (32 bytes, 40 at W = 16): the writer
// reads them for the same nodes, one cache line instead of five arrays' lines. Every field is
// written by the sweep (the programme's: split for interior nodes only; triangle_area for
// kOcclusion) before any read.
template <int W>
struct CollapseNode {
  double cost1;          // the programme's cost(node, 1)
  double triangle_area;  // the triangles' area under the node (kOcclusion)
  std::uint32_t refs;    // references under the node
  std::uint8_t split;    // a wide node's slots to the left child (of W)
  std::uint8_t pick[W];  // [k - 1] k = 1: 1 = leaf; k > 1: 0 = as k - 1, else slots to the left
};
static_assert(sizeof(CollapseNode<8>) == 32 && sizeof(CollapseNode<4>) == 32);

template <int W>
struct CollapseProgramme {
  using Row = std::array<double, W>;
  // A node's costs over 1..W slots, constant from `slots` on (at most its leaves, at most W).
  struct PendingRow {
    std::uint32_t node, slots;
    Row cost;
    // With `sizes`: over 1..W slots (as `collect` takes them), the leaf packets of the slots
    // (low 16 bits: at most W * slot_packets) plus the arena bytes of the interior slots'
    // subtrees << 16, so that one addition sums both; constant from `slots` on.
    std::array<std::uint64_t, W> size;
    PendingRow() {}  // filled where made (no zeroing first)
  };
  using Rows = std::vector<PendingRow>;  // pending rows, children before their parent
  CollapseNode<W>* info;                 // the collapser's, per node
  const WideCollapseOptions& o;
  // Unless null, each interior node's subtree as `write` lays it out from there (nodes of
  // `node_size` bytes, leaves' references distinct): its bytes << 16 | its own leaf lines.
  std::uint64_t* sizes = nullptr;
  std::size_t node_size = 0;

  CollapseProgramme(CollapseNode<W>* nodes, const WideCollapseOptions& opt) : info(nodes), o(opt) {}

  // Node i, once its children (if any) have been visited: its row replaces theirs.
  void visit(std::uint32_t i, const format::BvhNode& n, std::uint32_t refs, Rows& rows) {
    const double area = half_area(n);
    const double packets = double(packets_of(refs));
    const double leaf = area * (o.leaf_cost + o.packet_cost * packets);
    std::uint8_t* p = info[i].pick;
    if (n.count > 0) {
      PendingRow& row = rows.emplace_back();
      row.node = i, row.slots = 1;
      row.cost.fill(leaf);
      if (sizes) row.size.fill(slot_packets(refs));
      p[0] = 1;
      std::memset(p + 1, 0, W - 1);
      info[i].cost1 = leaf;
      return;
    }
    if (rows.size() < 2 || rows.back().node != i + 1 || rows[rows.size() - 2].node != n.offset)
      throw std::invalid_argument("collapse_bvh: binary nodes not in depth-first pre-order");
    const PendingRow& lr = rows.back();
    PendingRow& rr = rows[rows.size() - 2];  // becomes node i's row once read
    // (Each child's row has a slot or more: the max only tells the compiler.)
    const int slots = std::max(2, int(std::min<std::uint32_t>(W, lr.slots + rr.slots)));
    const int left_slots = int(lr.slots);
    double spread[W + 1];  // spread[k]: both children over k slots, k >= 2
    const Row &l = lr.cost, &r = rr.cost;
    for (int k = 2; k <= slots; ++k) spread[k] = spread_over(l, r, k, left_slots, p[k - 1]);
    // Beyond `slots` (< W), every share a spread tries meets both rows in their constant tails
    // (the left row from left_slots - 1 on, the right from its slots - 1 on), so each spread over
    // k > slots, W's included, sums the same doubles in the same order as over `slots`: the same
    // cost and pick. Fewer slots are as good there (cost kept, pick 0): the loops stop at `slots`.
    info[i].split = p[slots - 1];
    const double inner = area * o.node_cost + spread[slots];
    const bool as_leaf = refs <= o.max_leaf_refs && leaf <= inner;
    double c = as_leaf ? leaf : inner;  // the cost over k slots, written to rr's row
    p[0] = as_leaf ? 1 : 0;
    info[i].cost1 = c;
    rr.cost[0] = c;
    // Arithmetic selects (std::min: spread[k] < c, the same as !fewer), so that the compiler does
    // not branch on this data-dependent choice around the stores.
    for (int k = 2; k <= slots; ++k) {
      const bool fewer = c <= spread[k];  // as good with fewer slots
      c = std::min(c, spread[k]);
      rr.cost[k - 1] = c;
      p[k - 1] = std::uint8_t(p[k - 1] & (int(fewer) - 1));
    }
    std::fill(rr.cost.begin() + slots, rr.cost.end(), c);
    std::memset(p + slots, 0, std::size_t(W - slots));
    if (sizes) carry_sizes(i, refs, slots, lr, rr);
    rr.node = i, rr.slots = std::uint32_t(slots);
    rows.pop_back();
  }

  // The least cost of children rows `l` and `r` over k slots (the first on ties) and, in
  // `best_left`, the left child's share. Selects, not branches: the winners are data-dependent.
  // Shares above `left_slots` (from which l is constant) are not tried: there l is the same and
  // r (non-increasing) no less, so their sums are no less than at `left_slots`, which comes
  // first (rounding is monotone: the same picks and doubles as trying them). At the bottom of a
  // 16-wide tree this takes W's split from 15 sums to 1.
  static double spread_over(const Row& l, const Row& r, int k, int left_slots,
                            std::uint8_t& best_left) {
    double best = std::numeric_limits<double>::infinity();
    int pick = 0;  // in a register, not `best_left` (a store the compiler would branch around)
    const int last = std::min(k - 1, left_slots);
    for (int left = 1; left <= last; ++left) {
      const double s = l[left - 1] + r[k - left - 1];
      const bool better = s < best;
      best = better ? s : best;
      pick = better ? left : pick;
    }
    best_left = std::uint8_t(pick);
    return best;
  }

  bool is_leaf(std::uint32_t i) const { return info[i].pick[0] == 1; }

  // Interior node i's size (into `sizes`) and its row's sizes over 1..W slots, from its
  // children's rows `lr` (left) and `rr` (right, overwritten), its picks final: the sums
  // `subtree_size` would count, by the same picks.
  void carry_sizes(std::uint32_t i, std::uint32_t refs, int slots, const PendingRow& lr,
                   PendingRow& rr) {
    const std::uint8_t* p = info[i].pick;
    const int split = info[i].split;
    const std::uint64_t wide = lr.size[split - 1] + rr.size[W - split - 1];
    const std::uint64_t block =
        to_line(node_size + (wide & 0xffff) * sizeof(format::BvhTrianglePacket));
    const std::uint64_t bytes = block + (wide >> 16);
    sizes[i] = bytes << 16 | (block - node_size) / format::kBvhArenaLine;
    std::array<std::uint64_t, W> size;
    size[0] = p[0] == 1 ? slot_packets(refs) : bytes << 16;
    for (int k = 2; k <= slots; ++k) {
      const int left = p[k - 1];
      size[k - 1] = left == 0 ? size[k - 2] : lr.size[left - 1] + rr.size[k - left - 1];
    }
    // The same from `slots` on (picks 0 there); selects over all W, not a copy of `slots`.
    for (int k = 0; k < W; ++k) rr.size[k] = k < slots ? size[k] : size[slots - 1];
  }

  static std::size_t to_line(std::size_t bytes) {
    return (bytes + format::kBvhArenaLine - 1) / format::kBvhArenaLine * format::kBvhArenaLine;
  }

  // A leaf slot's packets, capped one past the format's limit (such a leaf is refused when
  // written, before its node's bytes): W of them fit the 16 bits they are summed in.
  static std::uint64_t slot_packets(std::uint32_t refs) {
    return std::min(packets_of(refs), format::kBvhMaxLeafPackets + 1);
  }

  // The slots subtree i (whose first reference is `first`) takes when given at most k.
  void collect(const FlatBvh& bin, std::uint32_t i, std::uint32_t first, std::uint32_t past, int k,
               Slots<W>& out) const {
    while (k > 1 && info[i].pick[k - 1] == 0) --k;
    if (k == 1 || bin.nodes[i].count > 0) {
      out.push(i, first, past);
      return;
    }
    const int left = info[i].pick[k - 1];
    collect(bin, i + 1, first, bin.nodes[i].offset, left, out);
    collect(bin, bin.nodes[i].offset, first + info[i + 1].refs, past, k - left, out);
  }
};

// Subtrees of at most this many references prefetch their triangles, and their positions.
constexpr std::uint32_t kPrefetchTriangles = 256, kPrefetchPositions = 64;

// Arrays carved one after another out of a caller's block (WideCollapseOptions::scratch: pages
// already touched, where a new block's would each fault) while it has room; an array that does
// not fit gets a block of its own.
class ScratchArrays {
 public:
  explicit ScratchArrays(UninitializedVector<std::byte>* block) : block_(block) {
    if (block_) block_->clear();
  }
  template <class T>
  std::span<T> take(std::size_t n, UninitializedVector<T>& own) {
    static_assert(std::is_trivially_copyable_v<T> &&
                  alignof(T) <= __STDCPP_DEFAULT_NEW_ALIGNMENT__);
    const std::size_t at = block_ ? (block_->size() + alignof(T) - 1) / alignof(T) * alignof(T) : 0;
    if (!block_ || at + n * sizeof(T) > block_->capacity()) {
      own.resize(n);
      return own;
    }
    block_->resize(at + n * sizeof(T));  // within its capacity: no new block, nothing zeroed
    return {reinterpret_cast<T*>(block_->data() + at), n};
  }

 private:
  UninitializedVector<std::byte>* block_;
};

template <int W>
struct Collapser {
  const FlatBvh& bin;
  const Scene* scene;  // corners from here when bin.triangles is empty
  FlatWideBvh& out;
  const WideCollapseOptions& options;
  // The arrays below lie in options.scratch while it has room, else in blocks of their own.
  UninitializedVector<CollapseNode<W>> own_info;
  UninitializedVector<double> own_ref_area;
  UninitializedVector<std::uint64_t> own_sizes;
  std::span<CollapseNode<W>> info;                // per binary node
  std::optional<CollapseProgramme<W>> programme;  // unless greedy
  const bool occlusion;                           // kOcclusion: triangle areas wanted
  std::span<double> ref_area;  // each reference's triangle's (kOcclusion, no copies)
  // Per interior node, its subtree's arena bytes << 16 | its own leaf lines, counted by the
  // programme in the sweep (2+ threads, distinct references); empty otherwise.
  std::span<std::uint64_t> sizes;

  Collapser(const FlatBvh& b, const Scene* s, FlatWideBvh& o, const WideCollapseOptions& opt,
            std::size_t node_size)
      : bin(b), scene(s), out(o), options(opt), occlusion(opt.order == WideSlotOrder::kOcclusion) {
    if (bin.triangles.empty() && scene == nullptr)
      throw std::invalid_argument("collapse_bvh: no leaf triangles and no scene");
    ScratchArrays scratch(opt.scratch);
    info = scratch.take(b.nodes.size(), own_info);
    if (!options.greedy) programme.emplace(info.data(), options);
    if (programme && bin.distinct_refs && resolve_thread_count(options.threads) > 1) {
      sizes = scratch.take(bin.nodes.size(), own_sizes);
      programme->sizes = sizes.data(), programme->node_size = node_size;
    }
    if (occlusion && bin.triangles.empty()) {
      ref_area = scratch.take(bin.prim_ids.size(), own_ref_area);
      reference_areas(bin, *scene, options.threads, ref_area);
    }
    sweep(options.threads);
  }

  std::uint32_t refs(std::uint32_t i) const { return info[i].refs; }

  // Node i's reference count, triangle area and programme row, its children's known.
  void visit(std::uint32_t i, typename CollapseProgramme<W>::Rows& rows) {
    const auto& n = bin.nodes[i];
    info[i].refs = n.count > 0 ? n.count : info[i + 1].refs + info[n.offset].refs;
    if (occlusion) info[i].triangle_area = subtree_triangle_area(i, n);
    if (programme) programme->visit(i, n, info[i].refs, rows);
  }

  // One past the last node of subtree i (pre-order: the end of its rightmost path).
  std::uint32_t subtree_end(std::uint32_t i) const {
    while (bin.nodes[i].count == 0) {
      if (bin.nodes[i].offset <= i || bin.nodes[i].offset >= bin.nodes.size())
        throw std::invalid_argument("collapse_bvh: binary nodes not in depth-first pre-order");
      i = bin.nodes[i].offset;
    }
    return i + 1;
  }

  // The binary subtrees swept apart (at most `limit` nodes each) and, in `top`, the nodes above
  // them, in pre-order.
  void split_sweep(std::uint32_t i, std::uint32_t limit, std::vector<std::uint32_t>& subtrees,
                   std::vector<std::uint32_t>& top) const {
    if (bin.nodes[i].count > 0 || subtree_end(i) - i <= limit) return subtrees.push_back(i);
    top.push_back(i);
    split_sweep(i + 1, limit, subtrees, top);
    split_sweep(bin.nodes[i].offset, limit, subtrees, top);
  }

  // Visits every node, children first: pre-order reversed. With threads, disjoint subtrees are
  // swept on their own and the nodes above them after, from their children's rows; every node's
  // arithmetic is the same either way.
  void sweep(unsigned threads) {
    using Rows = typename CollapseProgramme<W>::Rows;
    const auto n = std::uint32_t(bin.nodes.size());
    std::vector<std::uint32_t> subtrees, top;
    if (resolve_thread_count(threads) > 1 && n >= 65536)
      split_sweep(0, n / (8 * resolve_thread_count(threads)), subtrees, top);
    else
      subtrees.push_back(0);
    std::vector<Rows> done(subtrees.size());
    parallel_for(subtrees.size(), threads, [&](std::size_t t) {
      // The pending rows on this thread's stack, moved out once: neighbouring elements of `done`
      // share cache lines, which two threads pushing and popping rows would pass back and forth.
      Rows rows;
      for (std::uint32_t i = subtree_end(subtrees[t]); i-- > subtrees[t];) visit(i, rows);
      done[t] = std::move(rows);
    });
    if (top.empty()) return;
    Rows rows;  // the rows of the subtrees' roots and of the top nodes visited so far
    for (Rows& d : done) rows.insert(rows.end(), d.begin(), d.end());
    const auto take = [&](std::uint32_t node) {
      const auto it =
          std::find_if(rows.begin(), rows.end(), [&](auto& r) { return r.node == node; });
      auto row = *it;
      rows.erase(it);
      return row;
    };
    for (std::size_t j = top.size(); j-- > 0;) {
      const std::uint32_t i = top[j];
      Rows children;
      if (programme) children = {take(bin.nodes[i].offset), take(i + 1)};
      visit(i, children);
      rows.insert(rows.end(), children.begin(), children.end());
    }
  }

  // The triangles' area under node i, its children's already known.
  double subtree_triangle_area(std::uint32_t i, const format::BvhNode& n) const {
    if (n.count == 0) return info[i + 1].triangle_area + info[n.offset].triangle_area;
    double sum = 0;
    for (std::uint32_t r = n.offset; r < n.offset + n.count; ++r)
      sum += ref_area.empty() ? area_of(bin.triangles[r]) : ref_area[r];
    return sum;
  }

  // Every reference's triangle area, in leaf order, so that the sweep reads them in sequence.
  // The scene's triangles and positions are read in the leaves' scattered order, so each is
  // prefetched ahead (the triangle further ahead than its positions, which it locates), in
  // fixed chunks on the threads.
  static void reference_areas(const FlatBvh& bin, const Scene& scene, unsigned threads,
                              std::span<double> area) {
    constexpr std::size_t kChunk = 65536, kAheadTriangle = 256, kAheadPositions = 96;
    const std::size_t n = bin.prim_ids.size();
    parallel_for((n + kChunk - 1) / kChunk, threads, [&](std::size_t c) {
      const std::size_t end = std::min(n, (c + 1) * kChunk);
      for (std::size_t r = c * kChunk; r < end; ++r) {
        if (r + kAheadTriangle < end)
          __builtin_prefetch(&scene.triangles[bin.prim_ids[r + kAheadTriangle]]);
        if (r + kAheadPositions < end)
          for (const std::uint32_t v : scene.triangles[bin.prim_ids[r + kAheadPositions]].v)
            __builtin_prefetch(&scene.positions[v]);
        const auto& t = scene.triangles[bin.prim_ids[r]];
        area[r] =
            area_of({scene.positions[t.v[0]], scene.positions[t.v[1]], scene.positions[t.v[2]]});
      }
    });
  }

  static double area_of(const format::RayTriangle& t) {
    const format::Double3 a = to_d(t.v0), e1 = to_d(t.v1) - a, e2 = to_d(t.v2) - a;
    const format::Double3 n = cross(e1, e2);
    return 0.5 * std::sqrt(dot(n, n));
  }

  // Slots are ordered by decreasing score (any-hit traversal visits them in that order).
  double slot_score(std::uint32_t i) const {
    const double area = half_area(bin.nodes[i]);
    switch (options.order) {
      case WideSlotOrder::kLargestArea:
        return area;
      case WideSlotOrder::kOcclusion: {
        // P / C with P = min(1, triangle area / area) and C = cost / area: min(area, tri) / cost.
        // The greedy collapse has no programme: a rough cost instead.
        const CollapseNode<W>& c = info[i];
        const double cost = programme ? c.cost1 : area * (1.0 + double(c.refs) * 0.25);
        return cost > 0 ? std::min(area, c.triangle_area) / cost : 0.0;
      }
      default:
        return 0.0;
    }
  }

  bool is_leaf(std::uint32_t i) const {
    if (programme) return programme->is_leaf(i);
    return bin.nodes[i].count > 0 || refs(i) <= format::kBvhPacketSize;
  }

  // The references of binary subtree `i`, in leaf order (contiguous by pre-order).
  std::uint32_t first_ref(std::uint32_t i) const {
    while (bin.nodes[i].count == 0) i += 1;
    return bin.nodes[i].offset;
  }

  // Subtree `i`'s references (from `first`), one per triangle, appended to `list`: binary leaves
  // are deduplicated, but a presplit (or SBVH) triangle may sit in two binary leaves that become
  // one wide leaf (the duplicates are looked for among this subtree's references alone).
  void append_distinct_refs(std::uint32_t i, std::uint32_t first,
                            std::vector<std::uint32_t>& list) const {
    // A reference repeats one in the list iff its triangle is among the subtree's references
    // before it (each one's first is in the list): those ids are compared, in sequence and
    // without branches, instead of the listed references' ids.
    if (bin.distinct_refs) {  // no repeats to look for
      for (std::uint32_t r = first, end = r + refs(i); r < end; ++r) list.push_back(r);
      return;
    }
    const std::uint32_t* ids = bin.prim_ids.data();
    for (std::uint32_t r = first, end = r + refs(i); r < end; ++r) {
      bool seen = false;
      for (std::uint32_t q = first; q < r; ++q) seen |= ids[q] == ids[r];
      if (!seen) list.push_back(r);
    }
  }

  // The distinct references of node `kids`' leaf slots into `tally.leaf_refs` (slot k's from
  // tally.begin[k]; interior slots hold none), checked against the format's limit, and their
  // corners into `tally.corners`: every reference's triangle first, then every triangle's
  // positions, so that the loads of each pass do not wait on one another.
  void load_leaves(const Slots<W>& kids, WriteTally& tally) const {
    static_assert(W + 1 <= sizeof(WriteTally::begin) / sizeof(std::uint32_t));
    tally.leaf_refs.clear();
    for (int k = 0; k < kids.size; ++k) {
      tally.begin[std::size_t(k)] = std::uint32_t(tally.leaf_refs.size());
      if (!is_leaf(kids.node[k])) continue;
      append_distinct_refs(kids.node[k], kids.first[k], tally.leaf_refs);
      check_leaf(std::uint32_t(tally.leaf_refs.size() - tally.begin[std::size_t(k)]));
    }
    tally.begin[std::size_t(kids.size)] = std::uint32_t(tally.leaf_refs.size());
    const std::size_t n = tally.leaf_refs.size();
    tally.corners.resize(n);
    if (!bin.triangles.empty()) {
      for (std::size_t j = 0; j < n; ++j) tally.corners[j] = bin.triangles[tally.leaf_refs[j]];
      return;
    }
    tally.triangles.resize(n);
    for (std::size_t j = 0; j < n; ++j)
      tally.triangles[j] = scene->triangles[bin.prim_ids[tally.leaf_refs[j]]];
    for (std::size_t j = 0; j < n; ++j) {
      const format::Triangle& t = tally.triangles[j];
      tally.corners[j] = {scene->positions[t.v[0]], scene->positions[t.v[1]],
                          scene->positions[t.v[2]]};
    }
  }

  // Before subtree `i` (whose references start at `from`, its nodes end before `past`) is
  // written: the triangles of its references and its binary nodes and records, once it is small
  // enough (fetched ahead while its previous sibling is written: prefetch_next), and the
  // triangles' positions once it is smaller, fetched (each subtree once, not again for the
  // subtrees inside it), so that the walk and the packets below find them in cache.
  void prefetch(std::uint32_t i, std::uint32_t from, std::uint32_t past, WriteTally& tally) const {
    if (!bin.triangles.empty() || refs(i) > kPrefetchTriangles) return;
    prefetch_subtree(i, from, past, tally);
    const std::uint32_t to = from + refs(i);
    if (refs(i) > kPrefetchPositions || (from >= tally.positions_from && to <= tally.positions_to))
      return;
    for (std::uint32_t r = from; r < to; ++r) {
      const format::Triangle& t = scene->triangles[bin.prim_ids[r]];
      for (const std::uint32_t v : t.v) __builtin_prefetch(&scene->positions[v]);
    }
    tally.positions_from = from, tally.positions_to = to;
  }

  // The first interior slot from `k` on, prefetched (if small enough) while the slots before it
  // are written.
  void prefetch_next(const Slots<W>& kids, int k, WriteTally& tally) const {
    if (!bin.triangles.empty()) return;
    for (; k < kids.size; ++k)
      if (!is_leaf(kids.node[k])) {
        if (refs(kids.node[k]) <= kPrefetchTriangles)
          prefetch_subtree(kids.node[k], kids.first[k], kids.past[k], tally);
        return;
      }
  }

  // Subtree i's triangles, binary nodes and records, unless within one of the last two fetched.
  void prefetch_subtree(std::uint32_t i, std::uint32_t from, std::uint32_t past,
                        WriteTally& tally) const {
    const std::uint32_t to = from + refs(i);
    for (int s = 0; s < 2; ++s)
      if (from >= tally.triangles_from[s] && to <= tally.triangles_to[s]) return;
    for (std::uint32_t r = from; r < to; ++r)
      __builtin_prefetch(&scene->triangles[bin.prim_ids[r]]);
    // The subtree's binary nodes and records too: the writer reads them in slot order.
    prefetch_lines(&bin.nodes[i], &bin.nodes[0] + past);
    prefetch_lines(&info[i], &info[0] + past);
    const int s = tally.triangles_oldest;
    tally.triangles_from[s] = from, tally.triangles_to[s] = to, tally.triangles_oldest = 1 - s;
  }

  static void prefetch_lines(const void* from, const void* to) {
    for (auto* a = static_cast<const char*>(from); a < static_cast<const char*>(to); a += 64)
      __builtin_prefetch(a);
  }

  static std::uint32_t check_leaf(std::uint32_t count) {
    const std::uint32_t packets = packets_of(count);
    if (packets > format::kBvhMaxLeafPackets)
      throw std::invalid_argument("a BVH leaf of " + std::to_string(count) +
                                  " references does not fit a wide leaf");
    return packets;
  }

  // Packs leaf slot k of the node whose leaves load_leaves loaded into packets at byte `at` of
  // the arena; returns their count.
  std::uint8_t write_leaf(int k, std::size_t at, WriteTally& tally) const {
    const std::uint32_t* list = tally.leaf_refs.data() + tally.begin[std::size_t(k)];
    const format::RayTriangle* corners = tally.corners.data() + tally.begin[std::size_t(k)];
    const std::uint32_t count = tally.begin[std::size_t(k) + 1] - tally.begin[std::size_t(k)];
    const std::uint32_t packets = packets_of(count);
    tally.lanes_used += count;
    std::byte* dst = out.arena.data() + at;  // sized by `write`
    for (std::uint32_t p = 0; p < packets; ++p, dst += sizeof(format::BvhTrianglePacket)) {
      format::BvhTrianglePacket packet;
      for (std::uint32_t lane = 0; lane < format::kBvhPacketSize; ++lane) {
        // Unused lanes repeat the leaf's last triangle: every lane is a real triangle.
        const std::uint32_t j = std::min(p * format::kBvhPacketSize + lane, count - 1);
        const format::RayTriangle& t = corners[j];
        const format::Float3 c[3] = {t.v0, t.v1, t.v2};
        for (int v = 0; v < 3; ++v)
          for (int a = 0; a < 3; ++a) packet.v[v][a][lane] = format::at(c[v], a);
        packet.prim[lane] = bin.prim_ids[list[j]];
      }
      std::memcpy(dst, &packet, sizeof packet);
    }
    tally.leaf_count += 1;
    tally.packet_count += packets;
    return std::uint8_t(packets);
  }

  // The packets of a leaf slot, checked against the format's limit; its distinct references in
  // `scratch`.
  std::uint32_t leaf_packets(std::uint32_t i, std::uint32_t first,
                             std::vector<std::uint32_t>& scratch) const {
    if (bin.distinct_refs) return check_leaf(refs(i));
    scratch.clear();
    append_distinct_refs(i, first, scratch);
    return check_leaf(std::uint32_t(scratch.size()));
  }

  // The binary nodes that become node `i`'s children: the programme's slots, or (greedy) open
  // the largest child until W.
  Slots<W> gather(std::uint32_t i, std::uint32_t first, std::uint32_t past) const {
    Slots<W> kids;
    if (bin.nodes[i].count > 0 || (!programme && is_leaf(i))) {
      kids.push(i, first, past);
      return kids;
    }
    const std::uint32_t right = bin.nodes[i].offset;
    if (programme) {
      const int left = info[i].split;
      programme->collect(bin, i + 1, first, right, left, kids);
      programme->collect(bin, right, first + refs(i + 1), past, W - left, kids);
      return kids;
    }
    kids.push(i + 1, first, right), kids.push(right, first + refs(i + 1), past);
    while (kids.size < W) {
      int best = -1;
      float best_area = -1;
      for (int k = 0; k < kids.size; ++k)
        if (!is_leaf(kids.node[k]) && half_area(bin.nodes[kids.node[k]]) > best_area)
          best = k, best_area = half_area(bin.nodes[kids.node[k]]);
      if (best < 0) break;
      const std::uint32_t open = kids.node[best], open_first = kids.first[best];
      std::copy_backward(kids.node + best + 1, kids.node + kids.size, kids.node + kids.size + 1);
      std::copy_backward(kids.first + best + 1, kids.first + kids.size, kids.first + kids.size + 1);
      std::copy_backward(kids.past + best + 1, kids.past + kids.size, kids.past + kids.size + 1);
      kids.node[best] = open + 1, kids.node[best + 1] = bin.nodes[open].offset;
      kids.first[best] = open_first, kids.first[best + 1] = open_first + refs(open + 1);
      kids.past[best + 1] = kids.past[best], kids.past[best] = bin.nodes[open].offset;
      kids.size += 1;
    }
    return kids;
  }

  // Orders the slots by decreasing score, ties in the tree's order (a stable sort, each score
  // computed once): each slot's place is the count of slots ahead of it, greater or equal and
  // before, which takes no branches; with a NaN score (no order), an insertion sort instead.
  void order_slots(Slots<W>& kids) const {
    if (options.order == WideSlotOrder::kTree) return;
    double score[W];
    bool unordered = false;
    for (int k = 0; k < kids.size; ++k) {
      score[k] = slot_score(kids.node[k]);
      unordered |= score[k] != score[k];
    }
    if (unordered) return insertion_sort(kids, score);
    Slots<W> sorted;
    sorted.size = kids.size;
    for (int k = 0; k < kids.size; ++k) {
      int place = 0;
      for (int j = 0; j < kids.size; ++j)
        place += int(score[j] > score[k]) | (int(j < k) & int(score[j] == score[k]));
      sorted.node[place] = kids.node[k], sorted.first[place] = kids.first[k];
      sorted.past[place] = kids.past[k];
    }
    kids = sorted;
  }

  static void insertion_sort(Slots<W>& kids, double* score) {
    for (int k = 1; k < kids.size; ++k) {
      const std::uint32_t node = kids.node[k], first = kids.first[k], past = kids.past[k];
      const double key = score[k];
      int j = k;
      for (; j > 0 && key > score[j - 1]; --j) {
        kids.node[j] = kids.node[j - 1], kids.first[j] = kids.first[j - 1];
        kids.past[j] = kids.past[j - 1], score[j] = score[j - 1];
      }
      kids.node[j] = node, kids.first[j] = first, kids.past[j] = past, score[j] = key;
    }
  }

  // The arena, at least `end` bytes long: one writer grows it as it goes (amortised, from an
  // estimate); writers in parallel get it sized in full before, and only read its size here.
  std::byte* room(std::size_t end) const {
    if (out.arena.size() < end) out.arena.resize(end);
    return out.arena.data();
  }

  static std::uint32_t unit(std::size_t bytes) {
    if (bytes / format::kBvhArenaUnit >= format::kBvhLeafFlag)
      throw std::invalid_argument("BVH too large for 32-bit arena offsets");
    return std::uint32_t(bytes / format::kBvhArenaUnit);
  }
  static std::size_t to_line(std::size_t bytes) {
    return (bytes + format::kBvhArenaLine - 1) / format::kBvhArenaLine * format::kBvhArenaLine;
  }

  // The wide node of binary node `i` and its subtree, written into the arena (sized before, not
  // zeroed) at byte `at` (kiln/formats/bvh_wide.hpp): the node, its leaf packets, zeros to the
  // next line, then its interior children's subtrees. Returns the end of the subtree; sets
  // `leaf_lines` to the lines its own leaf packets span. Interior children listed in `top` are
  // not written: their places (sized by `top`) are recorded there for writers of their own.
  template <class Node>
  std::size_t write(std::uint32_t i, std::uint32_t first, std::uint32_t past, std::uint32_t depth,
                    std::size_t at, std::size_t& leaf_lines, WriteTally& tally,
                    TopLevels* top = nullptr) const {
    tally.node_count += 1;
    tally.max_depth = std::max(tally.max_depth, depth);
    format::BvhWideNode<W> node{};
    for (int a = 0; a < 3; ++a)
      for (int k = 0; k < W; ++k) {
        node.bounds[a][0][k] = std::numeric_limits<float>::infinity();
        node.bounds[a][1][k] = -std::numeric_limits<float>::infinity();
      }
    for (int k = 0; k < W; ++k) node.child[k] = format::kBvhLeafFlag;
    prefetch(i, first, past, tally);
    Slots<W> kids = gather(i, first, past);
    order_slots(kids);
    prefetch_next(kids, 0, tally);
    load_leaves(kids, tally);
    std::size_t end = at + sizeof(Node);
    // The arena holds the node and its leaf packets from here on (one resize per node at most).
    std::size_t leaf_bytes = 0;
    for (int k = 0; k < kids.size; ++k)
      leaf_bytes +=
          packets_of(tally.begin[k + 1] - tally.begin[k]) * sizeof(format::BvhTrianglePacket);
    room(to_line(end + leaf_bytes));
    for (int k = 0; k < kids.size; ++k) {
      const auto& b = bin.nodes[kids.node[k]];
      for (int a = 0; a < 3; ++a) node.bounds[a][0][k] = b.min[a], node.bounds[a][1][k] = b.max[a];
      if (!is_leaf(kids.node[k])) continue;
      node.child[k] = format::kBvhLeafFlag | unit(end);
      node.packets[k] = write_leaf(k, end, tally);
      end += node.packets[k] * sizeof(format::BvhTrianglePacket);
    }
    leaf_lines = to_line(end - at - sizeof(Node)) / format::kBvhArenaLine;
    std::memset(out.arena.data() + end, 0, to_line(end) - end);  // the arena is not zeroed
    end = to_line(end);
    for (int k = 0; k < kids.size; ++k) {
      if (is_leaf(kids.node[k])) continue;
      std::size_t child_lines = 0;
      node.child[k] = unit(end);
      prefetch_next(kids, k + 1, tally);
      if (top && top->has(kids.node[k])) {
        const TopLevels::Subtree& sub = top->take(end);
        child_lines = sub.leaf_lines, end += sub.bytes;
      } else {
        end = write<Node>(kids.node[k], kids.first[k], kids.past[k], depth + 1, end, child_lines,
                          tally, top);
      }
      node.packets[k] = std::uint8_t(std::min<std::size_t>(child_lines, 255));
    }
    if constexpr (std::is_same_v<Node, format::BvhWideNode<W>>) {
      std::memcpy(out.arena.data() + at, &node, sizeof node);
    } else {
      const Node q = quantize(node);
      std::memcpy(out.arena.data() + at, &q, sizeof q);
    }
    return end;
  }

  // What `write` will write for binary node `i`: bytes and the node's own leaf lines.
  std::pair<std::size_t, std::size_t> subtree_size(std::uint32_t i, std::uint32_t first,
                                                   std::uint32_t past, std::size_t node_size,
                                                   std::vector<std::uint32_t>& scratch) const {
    const Slots<W> kids = gather(i, first, past);
    const std::size_t block = to_line(leaf_block(kids, node_size, scratch));
    std::size_t below = 0;
    for (int k = 0; k < kids.size; ++k)
      if (!is_leaf(kids.node[k]))
        below += subtree_size(kids.node[k], kids.first[k], kids.past[k], node_size, scratch).first;
    return {block + below, (block - node_size) / format::kBvhArenaLine};
  }

  // A node's bytes with its leaf slots' packets (before the line padding).
  std::size_t leaf_block(const Slots<W>& kids, std::size_t node_size,
                         std::vector<std::uint32_t>& scratch) const {
    std::size_t block = node_size;
    for (int k = 0; k < kids.size; ++k)
      if (is_leaf(kids.node[k]))
        block +=
            leaf_packets(kids.node[k], kids.first[k], scratch) * sizeof(format::BvhTrianglePacket);
    return block;
  }

  // The places (and depths) of the subtrees in `top` (sizes counted), in the order `write` meets
  // them below node `i` written at byte `at`; returns the end of node i's subtree.
  std::size_t place_top(std::uint32_t i, std::uint32_t first, std::uint32_t past, std::size_t at,
                        std::uint32_t depth, std::size_t node_size, TopLevels& top,
                        std::vector<std::uint32_t>& scratch) const {
    Slots<W> kids = gather(i, first, past);
    order_slots(kids);
    std::size_t end = at + to_line(leaf_block(kids, node_size, scratch));
    for (int k = 0; k < kids.size; ++k) {
      const std::uint32_t kid = kids.node[k];
      if (is_leaf(kid)) continue;
      if (top.has(kid)) {
        TopLevels::Subtree& sub = top.subtrees[top.next++];
        sub.at = end, sub.depth = depth + 1;
        end += sub.bytes;
      } else {
        end = place_top(kid, kids.first[k], kids.past[k], end, depth + 1, node_size, top, scratch);
      }
    }
    return end;
  }

  // The interior slots below the top levels, in the order `write` meets them: each subtree of at
  // most `limit` references (or a leaf's parent) is written apart.
  void find_top_subtrees(std::uint32_t i, std::uint32_t first, std::uint32_t past,
                         std::uint32_t limit, TopLevels& top) const {
    Slots<W> kids = gather(i, first, past);
    order_slots(kids);
    for (int k = 0; k < kids.size; ++k) {
      const std::uint32_t kid = kids.node[k];
      if (is_leaf(kid)) continue;
      if (refs(kid) <= limit)
        top.subtrees.push_back({kid, kids.first[k], kids.past[k]});
      else
        find_top_subtrees(kid, kids.first[k], kids.past[k], limit, top);
    }
  }
};

// The tree by index (FlatWideBvh::nodes and packets) read back from the arena: nodes in the
// order written (pre-order, slots in order), packets in the order a walk in slot order meets
// them; child words index those, interior children's `packets` 0.
template <class Node, int W>
struct IndexTreeReader {
  FlatWideBvh& wide;

  std::uint32_t read(std::uint32_t offset) {
    Node n;
    std::memcpy(&n, wide.arena.data() + std::size_t(offset) * format::kBvhArenaUnit, sizeof n);
    const auto index = std::uint32_t(wide.nodes.size() / sizeof n);
    wide.nodes.resize(wide.nodes.size() + sizeof n);
    for (int k = 0; k < W; ++k) {
      if (n.child[k] & format::kBvhLeafFlag) {
        if (n.packets[k] == 0) continue;  // empty slot
        const auto* p = reinterpret_cast<const format::BvhTrianglePacket*>(
            wide.arena.data() +
            std::size_t(n.child[k] & ~format::kBvhLeafFlag) * format::kBvhArenaUnit);
        n.child[k] = format::kBvhLeafFlag | std::uint32_t(wide.packets.size());
        wide.packets.insert(wide.packets.end(), p, p + n.packets[k]);
      } else {
        n.child[k] = read(n.child[k]);
        n.packets[k] = 0;
      }
    }
    std::memcpy(wide.nodes.data() + std::size_t(index) * sizeof n, &n, sizeof n);
    return index;
  }
};

void size_arena(UninitializedVector<std::byte>& arena, std::size_t bytes) {
  reserve_huge(arena, bytes);
  arena.resize(bytes);
}

// The subtrees below the top levels (at 2+ threads), each written apart into its place. One
// worker writes them in arena order from the first, each at the end of the one before plus the
// top-level bytes between them, without sizing them first (it alone grows the arena meanwhile);
// the others size them from the last back, until the two meet. `ends` holds the next one to
// write (low word) and the first one sized (high word). Returns how many were written.
template <class Node, int W>
std::size_t write_or_size(const Collapser<W>& c, TopLevels& top, std::vector<WriteTally>& tallies,
                          unsigned threads) {
  const std::size_t n = top.subtrees.size();
  std::vector<std::size_t> gap(n);  // the top-level bytes before each one (places with all empty)
  for (std::size_t j = 0; j < n; ++j)
    gap[j] = top.subtrees[j].at - (j > 0 ? top.subtrees[j - 1].at : 0);
  std::atomic<std::uint64_t> ends{std::uint64_t(n) << 32};
  std::atomic<std::size_t> written{0};
  parallel_for(threads, threads, [&](std::size_t w) {
    std::size_t end = 0;
    for (std::uint64_t v = ends.load();;) {
      const auto next = std::uint32_t(v), sized = std::uint32_t(v >> 32);
      if (next >= sized) break;
      if (!ends.compare_exchange_weak(v, w == 0 ? v + 1 : v - (std::uint64_t(1) << 32))) continue;
      TopLevels::Subtree& sub = top.subtrees[w == 0 ? next : sized - 1];
      if (w == 0) {
        sub.at = end + gap[next];
        end = c.template write<Node>(sub.node, sub.first, sub.past, sub.depth, sub.at,
                                     sub.leaf_lines, tallies[next]);
        sub.bytes = end - sub.at;
        written.store(next + 1, std::memory_order_relaxed);
      } else {
        std::tie(sub.bytes, sub.leaf_lines) =
            c.subtree_size(sub.node, sub.first, sub.past, sizeof(Node), tallies[sized - 1].scratch);
      }
      v = ends.load();
    }
  });
  return written.load();
}

// Writes the arena at 2+ threads: the subtrees below the top levels are written apart (first by
// write_or_size, then the rest, once placed, beside the top levels). The same bytes as one writer.
template <class Node, int W>
void write_apart(const Collapser<W>& c, std::uint32_t first, std::uint32_t past, unsigned threads,
                 FlatWideBvh& out, WriteTally& tally, std::size_t& root_lines) {
  TopLevels top;
  c.find_top_subtrees(0, first, past, std::max<std::uint32_t>(c.info[0].refs / (16 * threads), 64),
                      top);
  std::vector<WriteTally> tallies(top.subtrees.size());
  std::size_t written = 0;
  if (!c.sizes.empty()) {  // counted in the sweep
    for (TopLevels::Subtree& sub : top.subtrees)
      sub.bytes = c.sizes[sub.node] >> 16, sub.leaf_lines = c.sizes[sub.node] & 0xffff;
  } else {
    c.place_top(0, first, past, 0, 1, sizeof(Node), top, tally.scratch);  // depths, gaps
    reserve_huge(out.arena, std::size_t(c.info[0].refs) * 80 + sizeof(Node));
    written = write_or_size<Node>(c, top, tallies, threads);
  }
  std::vector<std::size_t> at(written);
  for (std::size_t j = 0; j < written; ++j) at[j] = top.subtrees[j].at;
  top.next = 0;
  size_arena(out.arena, c.place_top(0, first, past, 0, 1, sizeof(Node), top, tally.scratch));
  if (top.next != top.subtrees.size())  // every place reserved, in the order found
    throw std::logic_error("collapse_bvh: the top levels met their subtrees out of order");
  for (std::size_t j = 0; j < written; ++j)
    if (top.subtrees[j].at != at[j])
      throw std::logic_error("collapse_bvh: a subtree written out of its place");
  top.next = 0;
  // The top levels are one more task beside the subtrees: their few nodes lie between the
  // subtrees, each on a page of the arena to fault in.
  parallel_for(top.subtrees.size() - written + 1, threads, [&](std::size_t t) {
    if (t == 0) {
      c.template write<Node>(0, first, past, 1, 0, root_lines, tally, &top);
      return;
    }
    const auto& sub = top.subtrees[written + t - 1];
    std::size_t lines = 0;
    const std::size_t end = c.template write<Node>(sub.node, sub.first, sub.past, sub.depth, sub.at,
                                                   lines, tallies[written + t - 1]);
    if (end != sub.at + sub.bytes || lines != sub.leaf_lines)  // sizes counted in the sweep
      throw std::logic_error("collapse_bvh: a subtree written apart is not the size counted");
  });
  for (const WriteTally& t : tallies) tally.add(t);
}

template <int W, class Node>
std::uint64_t collapse_into(const FlatBvh& binary, const Scene* scene,
                            const WideCollapseOptions& options, FlatWideBvh& out) {
  const Collapser<W> collapser(binary, scene, out, options, sizeof(Node));
  const unsigned threads = resolve_thread_count(options.threads);
  WriteTally tally;
  std::size_t root_lines = 0;
  const std::uint32_t first = binary.nodes.empty() ? 0 : collapser.first_ref(0);
  const auto past = std::uint32_t(binary.nodes.size());
  if (threads == 1 || collapser.is_leaf(0)) {
    // One writer appends (pre-order), so no sizing pass: the arena grows from an estimate
    // (reserved, so untouched pages cost nothing) and is cut to the bytes written.
    reserve_huge(out.arena, std::size_t(collapser.info.empty() ? 0 : collapser.info[0].refs) * 80 +
                                sizeof(Node));
    out.arena.resize(collapser.template write<Node>(0, first, past, 1, 0, root_lines, tally));
  } else {
    write_apart<Node>(collapser, first, past, threads, out, tally, root_lines);
  }
  out.stats.node_count = tally.node_count, out.stats.leaf_count = tally.leaf_count;
  out.stats.packet_count = tally.packet_count, out.stats.max_depth = tally.max_depth;
  if (collapser.programme && !binary.nodes.empty())
    out.stats.sah_cost = collapser.info[0].cost1 / half_area(binary.nodes[0]);
  if (options.index_tree) IndexTreeReader<Node, W>{out}.read(0);
  return tally.lanes_used;
}

}  // namespace

FlatWideBvh collapse_bvh(const FlatBvh& binary, std::uint32_t width, std::size_t triangle_count,
                         bool quantized, const Scene* scene, const WideCollapseOptions& options) {
  FlatWideBvh out;
  out.width = width;
  out.quantized = quantized;
  std::uint64_t lanes_used = 0;
  if (width == 4)
    lanes_used = quantized ? collapse_into<4, format::BvhQNode4>(binary, scene, options, out)
                           : collapse_into<4, format::BvhNode4>(binary, scene, options, out);
  else if (width == 8)
    lanes_used = quantized ? collapse_into<8, format::BvhQNode8>(binary, scene, options, out)
                           : collapse_into<8, format::BvhNode8>(binary, scene, options, out);
  else if (width == 16 && !quantized)
    lanes_used = collapse_into<16, format::BvhNode16>(binary, scene, options, out);
  else if (width == 16)
    throw std::invalid_argument("16-wide BVH nodes have float boxes only");
  else
    throw std::invalid_argument("BVH width " + std::to_string(width) + " is not 4, 8 or 16");
  auto& s = out.stats;
  s.packet_fill =
      s.packet_count ? double(lanes_used) / double(s.packet_count * format::kBvhPacketSize) : 0;
  s.arena_bytes = out.arena.size();
  s.bytes_per_triangle = double(s.arena_bytes) / double(std::max<std::size_t>(triangle_count, 1));
  return out;
}

}  // namespace kiln
