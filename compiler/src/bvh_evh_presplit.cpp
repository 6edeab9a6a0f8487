// Edge volume heuristic presplit (bvh_evh_presplit.hpp).
#include "bvh_evh_presplit.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "kiln/runtime/parallel.hpp"

namespace kiln {

namespace {

using format::Double3;

// A piece of a triangle in double (midpoints of float corners stay exact for many halvings),
// with its largest edge volume and that edge (corner `edge` to corner `edge + 1`).
struct Piece {
  Double3 p[3];
  double volume = 0;
  int edge = 0;
};

void measure(Piece& piece) {
  piece.volume = -1;
  for (int e = 0; e < 3; ++e) {
    const double v = edge_volume(piece.p[e], piece.p[(e + 1) % 3]);
    if (v > piece.volume) piece.volume = v, piece.edge = e;
  }
}

Piece make_piece(const Double3& a, const Double3& b, const Double3& c) {
  Piece piece{{a, b, c}};
  measure(piece);
  return piece;
}

using Pieces = std::array<Piece, kEvhMaxRefsLimit>;

// The triangle's pieces, largest edge volume first: the same greedy order whatever the budget,
// so a larger max_refs only ever refines a smaller one's pieces.
std::uint32_t subdivide(const format::Float3 (&corners)[3], double threshold,
                        std::uint32_t max_refs, Pieces& pieces) {
  max_refs = std::clamp<std::uint32_t>(max_refs, 1, kEvhMaxRefsLimit);
  pieces[0] =
      make_piece(format::to_d(corners[0]), format::to_d(corners[1]), format::to_d(corners[2]));
  std::uint32_t n = 1;
  while (n < max_refs) {
    std::uint32_t best = 0;
    for (std::uint32_t i = 1; i < n; ++i)
      if (pieces[i].volume > pieces[best].volume) best = i;
    if (!(pieces[best].volume > threshold)) break;
    const Piece whole = pieces[best];
    const Double3 a = whole.p[whole.edge], b = whole.p[(whole.edge + 1) % 3],
                  c = whole.p[(whole.edge + 2) % 3];
    const Double3 m = (a + b) * 0.5;
    pieces[best] = make_piece(a, m, c);
    pieces[n++] = make_piece(m, b, c);
  }
  return n;
}

// The float box around a piece: its double box widened by a margin far above the double
// rounding of the midpoints, rounded outwards, then clamped into the triangle's own box (which
// contains the whole triangle exactly).
format::Box3f piece_box(const Piece& piece, const format::Box3f& triangle_box) {
  double scale = 0;
  for (const Double3& p : piece.p)
    for (int a = 0; a < 3; ++a) scale = std::max(scale, std::fabs(format::at(p, a)));
  const double margin = std::ldexp(scale, -40);
  format::Box3f box;
  for (int a = 0; a < 3; ++a) {
    double lo = format::at(piece.p[0], a), hi = lo;
    for (const Double3& p : piece.p)
      lo = std::min(lo, format::at(p, a)), hi = std::max(hi, format::at(p, a));
    float flo = float(lo - margin), fhi = float(hi + margin);
    if (double(flo) > lo - margin)
      flo = std::nextafter(flo, -std::numeric_limits<float>::infinity());
    if (double(fhi) < hi + margin)
      fhi = std::nextafter(fhi, std::numeric_limits<float>::infinity());
    format::at(box.min, a) = std::max(flo, format::at(triangle_box.min, a));
    format::at(box.max, a) = std::min(fhi, format::at(triangle_box.max, a));
  }
  return box;
}

struct Triangle {
  format::Float3 corners[3];
  format::Box3f box;
};

Triangle triangle_of(const Scene& scene, std::size_t i) {
  Triangle t;
  for (int c = 0; c < 3; ++c) {
    t.corners[c] = scene.positions[scene.triangles[i].v[c]];
    t.box.grow(t.corners[c]);
  }
  return t;
}

double box_volume(const format::Box3f& b) {
  if (b.empty()) return 0.0;
  return (double(b.max.x) - b.min.x) * (double(b.max.y) - b.min.y) * (double(b.max.z) - b.min.z);
}

}  // namespace

double edge_volume(const format::Double3& a, const format::Double3& b) {
  return std::fabs((a.x - b.x) * (a.y - b.y) * (a.z - b.z));
}

std::uint32_t evh_piece_count(const format::Float3 (&corners)[3], double threshold,
                              std::uint32_t max_refs) {
  Pieces pieces;
  return subdivide(corners, threshold, max_refs, pieces);
}

std::vector<PrimRef> evh_presplit_refs(const Scene& scene, const BvhBuildOptions& options) {
  const std::size_t n = scene.triangles.size();
  format::Box3f scene_box;
  for (const format::Float3& p : scene.positions) scene_box.grow(p);
  const double threshold = options.evh_threshold * box_volume(scene_box);
  constexpr std::size_t kBatch = 16384;
  std::vector<std::uint32_t> first(n + 1, 0);  // counts, then each triangle's first reference
  parallel_for_batched(n, kBatch, options.threads, [&](std::size_t i) {
    thread_local Pieces pieces;
    first[i + 1] =
        subdivide(triangle_of(scene, i).corners, threshold, options.evh_max_refs, pieces);
  });
  std::uint64_t total = 0;
  for (std::size_t i = 1; i <= n; ++i) {
    total += first[i];
    if (total > std::numeric_limits<std::uint32_t>::max())
      throw std::runtime_error("BVH: the EVH presplit makes more than 2^32 - 1 references");
    first[i] = std::uint32_t(total);
  }
  std::vector<PrimRef> refs(total);
  parallel_for_batched(n, kBatch, options.threads, [&](std::size_t i) {
    thread_local Pieces pieces;
    const Triangle t = triangle_of(scene, i);
    const std::uint32_t count = first[i + 1] - first[i];
    if (count == 1) {  // whole: exactly the unsplit reference
      refs[first[i]] = {t.box, std::uint32_t(i)};
      return;
    }
    subdivide(t.corners, threshold, options.evh_max_refs, pieces);
    for (std::uint32_t k = 0; k < count; ++k)
      refs[first[i] + k] = {piece_box(pieces[k], t.box), std::uint32_t(i)};
  });
  return refs;
}

}  // namespace kiln
