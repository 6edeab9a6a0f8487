// Builds the polygon index (docs/FORMAT.md, "Polygon index") over a polygon layer: a region
// quadtree over the layer's bounds, split while a cell lists more than `max_edges` edges, whose
// leaves mark each polygon wholly inside, or list its edges meeting the cell and whether the
// cell's centre is inside.
#pragma once

#include <cstdint>
#include <vector>

#include "kiln/compiler/geo_layer.hpp"
#include "kiln/formats/polygon_index.hpp"
#include "kiln/runtime/geo_layer.hpp"

namespace kiln {

struct PolygonIndexBuildOptions {
  std::uint32_t max_edges = 8;   ///< a cell listing more edges splits...
  std::uint32_t max_depth = 16;  ///< ...until this depth (root = 0)
  unsigned threads = 0;          ///< 0 = every core; never changes the result
};

/// The flattened index, ready to write as sections.
struct FlatPolygonIndex {
  std::vector<format::PolygonIndexNode> nodes;
  std::vector<format::PolygonIndexEntry> entries;
  std::vector<format::PolygonIndexEdge> edges;
  format::Box2d bounds;  ///< the root cell
  std::uint64_t leaf_count = 0;
  std::uint32_t depth = 0;  ///< deepest leaf
};

/// Spans over an in-memory layer (it must outlive the view).
PolygonLayerView view_of(const PolygonLayer& layer);

/// Builds the index; byte-identical for any thread count. Throws std::invalid_argument when the
/// layer has more than 2^32 - 2 polygons or 2^31 - 1 vertices.
FlatPolygonIndex build_polygon_index(const PolygonLayerView& layer,
                                     const PolygonIndexBuildOptions& options);

}  // namespace kiln
