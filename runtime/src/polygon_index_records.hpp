// The polygon index's leaf records (PolygonIndexTopGrid::records, docs/FORMAT.md "Leaf
// records"): their answer for a point, one kernel per instruction set, chosen at open. Private
// to the runtime.
#pragma once

#include <cstdint>

#include "kiln/formats/vector.hpp"
#include "kiln/runtime/polygon_index.hpp"

namespace kiln::polygon_records {

/// A record group's words before its blocks: {edge blocks, centre mask}, centre x, centre y.
inline constexpr std::size_t kHeadWords = 3;
/// A block of four edges: a.x[4], a.y[4], b.x[4], b.y[4], then four uint32 masks.
inline constexpr std::size_t kBlockWords = 18;

using Kernel = PolygonRecordKernel;

enum class KernelKind { kScalar, kSse2, kAvx2 };

/// Whether this build and CPU can run `kind`.
bool supported(KernelKind kind);
Kernel kernel(KernelKind kind);
/// The fastest supported, or the one KILN_POLYGON_KERNEL names (scalar, sse2, avx2; an
/// unsupported or unknown name throws std::invalid_argument).
KernelKind best_kernel();

}  // namespace kiln::polygon_records
