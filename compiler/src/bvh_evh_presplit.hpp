// The edge volume heuristic (Dammertz & Keller 2008, "Edge Volume Heuristic - Robust Triangle
// Subdivision for Improved BVH Performance"): long diagonal triangles have boxes that are mostly
// empty, so the SAH builders cannot separate them; halving such triangles before the build gives
// references with tight boxes. The pieces are not new triangles: each piece's box becomes one
// build reference carrying the original triangle's id (as SBVH references do).
#pragma once

#include <cstdint>
#include <vector>

#include "kiln/compiler/bvh_builder.hpp"

namespace kiln {

/// The most references one triangle may become (the bound of BvhBuildOptions::evh_max_refs).
inline constexpr std::uint32_t kEvhMaxRefsLimit = 64;

/// The volume of the axis-aligned box spanned by the segment a-b (0 when it is axis-parallel).
double edge_volume(const format::Double3& a, const format::Double3& b);

/// How many references the triangle `corners` becomes: while fewer than `max_refs` (clamped to
/// 1..kEvhMaxRefsLimit), the piece whose largest edge volume is largest (first piece on ties)
/// is halved at the midpoint of that edge, as long as that volume exceeds `threshold` (absolute,
/// in cubic scene units).
std::uint32_t evh_piece_count(const format::Float3 (&corners)[3], double threshold,
                              std::uint32_t max_refs);

/// The build references of the EVH presplit, in triangle order, each triangle's pieces together:
/// piece boxes widened by a rounding margin and clamped into the triangle's box, so the boxes of
/// a triangle's pieces cover it and a triangle left whole keeps its exact box. The threshold is
/// options.evh_threshold x the volume of the scene's box. Counts per triangle, a prefix sum and
/// a fill, both passes in parallel: the same references on any thread count. Throws
/// std::runtime_error beyond 2^32 - 1 references.
std::vector<PrimRef> evh_presplit_refs(const Scene& scene, const BvhBuildOptions& options);

}  // namespace kiln
