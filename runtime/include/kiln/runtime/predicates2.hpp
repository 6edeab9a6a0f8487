// Exact 2D geometric predicates on doubles: Shewchuk's adaptive orientation test ("Adaptive
// Precision Floating-Point Arithmetic and Fast Robust Geometric Predicates", 1997), and the
// point-in-ring crossing test built on it that defines Kiln's half-open boundary rule
// (docs/FORMAT.md, "Polygon index: boundary rule").
//
// The error bounds assume every product and sum is rounded to double on its own: the library is
// compiled with -ffp-contract=off (no fused multiply-add), and these functions live in a .cpp of
// their own so that a caller's flags cannot contract them.
#pragma once

#include <span>

#include "kiln/formats/vector.hpp"

namespace kiln {

/// Twice the signed area of triangle (a, b, c), with the exact sign: > 0 when c lies to the left
/// of the directed line a -> b (counter-clockwise), < 0 to its right, 0 exactly when collinear.
/// The magnitude is an approximation; only the sign is exact. Finite inputs only (NaN or
/// infinities give an unspecified sign but never crash).
double orient2d(const format::Double2& a, const format::Double2& b, const format::Double2& c);

/// The crossing test of the half-open rule: whether the horizontal ray from `p` towards +x
/// crosses edge (a, b) — the edge spans p.y half-open (min(a.y, b.y) <= p.y < max(a.y, b.y))
/// and p lies strictly left of it. A point exactly on the edge does not count. Exact.
bool crosses_ray(const format::Double2& a, const format::Double2& b, const format::Double2& p);

/// Whether the segment from `c` to `p`, both ends moved by the rule's infinitesimal shift
/// (+eps, +delta) with 0 < delta << eps, crosses edge (a, b). The shift puts the segment in
/// general position (it passes through no vertex, its ends lie on no edge, it overlaps no
/// edge), so summed over closed rings the crossings' parity is exactly the change of the
/// half-open rule's answer from c to p. Exact (simulation of simplicity on orient2d's signs).
bool shifted_segment_crosses(const format::Double2& c, const format::Double2& p,
                             const format::Double2& a, const format::Double2& b);

/// Whether the closed segment (a, b) meets the closed box [lo, hi]. Exact.
bool segment_meets_box(const format::Double2& a, const format::Double2& b,
                       const format::Double2& lo, const format::Double2& hi);

/// Parity of crossings of the ray from `p` with the closed ring `ring` (vertices in order, the
/// closing edge implied): true when p is inside the ring under the half-open rule.
bool ring_contains(std::span<const format::Double2> ring, const format::Double2& p);

}  // namespace kiln
