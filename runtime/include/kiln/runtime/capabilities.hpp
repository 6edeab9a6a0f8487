// What an opened structure can answer, one small interface per capability. Tools ask a
// StructureView for a capability and get nullptr when the structure lacks it; they never name
// a structure. The concrete views (one per kind) offer the same operations without virtual
// calls, for code that knows what it holds.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "kiln/formats/geometry.hpp"
#include "kiln/formats/vector.hpp"
#include "kiln/runtime/query_results.hpp"
#include "kiln/runtime/ray.hpp"
#include "kiln/runtime/voxel_grid.hpp"

namespace kiln {

/// A hit seen as a surface to draw: the hit (t, prim) and the normal to shade with (a
/// triangle's geometric normal; a voxel's attached normal, else the entered face or contour
/// plane), not normalised and possibly zero.
struct SurfaceHit {
  Hit hit;
  format::Float3 normal{0, 0, 0};
};

/// Ray casting: closest hit, first hit found, counted casts.
class RayQueries {
 public:
  virtual ~RayQueries() = default;
  /// Bytes of one record in a HITS file: sizeof(Hit) or sizeof(VoxelHitRecord).
  virtual std::size_t record_size() const = 0;
  /// One record per ray into `records` (rays.size() * record_size() bytes), closest hits or,
  /// with `any_hit`, the first hit found; on up to `threads` threads (0 = all cores).
  virtual void trace_records(std::span<const Ray> rays, std::span<std::byte> records, bool any_hit,
                             unsigned threads) const = 0;
  /// The closest hit of one ray (its Hit part for voxel structures).
  virtual Hit closest(const Ray& ray) const = 0;
  /// The closest hit of one ray as a surface, counting the work into `cost`.
  virtual SurfaceHit intersect_counting(const Ray& ray, Cost& cost) const = 0;
  /// Voxel structures: the closest hit with its voxel, normals and stored colour (the hit
  /// trace_records writes, plus the colour); false, nothing written, for triangle structures.
  virtual bool closest_voxel(const Ray& ray, VoxelHit& out) const {
    (void)ray, (void)out;
    return false;
  }
  /// Whether voxel hits carry a stored colour (an ESVO built from coloured input).
  virtual bool has_colors() const { return false; }
  /// Voxel structures: the finest grid (origin, voxel size, resolution) into `out`, true; false,
  /// nothing written, for triangle structures.
  virtual bool voxel_frame(VoxelGridFrame& out) const {
    (void)out;
    return false;
  }
};

/// Proximity on a triangle surface: closest point, inside/outside (by ray parity; meaningful
/// for closed meshes), every triangle overlapping a box (sorted, unique ids).
class SurfaceQueries {
 public:
  virtual ~SurfaceQueries() = default;
  virtual ClosestPoint closest_point(const format::Float3& p, float max_distance) const = 0;
  virtual bool inside(const format::Float3& p) const = 0;
  virtual void triangles_in_box(const format::Float3& lo, const format::Float3& hi,
                                std::vector<std::uint32_t>& out) const = 0;
};

/// Nearest neighbours in a 3D point set, sorted by (distance, id) as a brute-force scan sorts.
class NeighborQueries {
 public:
  virtual ~NeighborQueries() = default;
  /// The min(k, point count) nearest, k = out.size(); returns how many were written.
  virtual std::size_t nearest(const format::Float3& query, std::span<Neighbor> out) const = 0;
  /// Every point with squared distance <= radius^2, into `out` (cleared first).
  virtual void within_radius(const format::Float3& query, float radius,
                             std::vector<Neighbor>& out) const = 0;
};

/// Occupancy of space: whether a world-space point lies in the structure's solid.
class OccupancyQueries {
 public:
  virtual ~OccupancyQueries() = default;
  virtual bool occupied(const format::Float3& point) const = 0;
};

/// A cell of a 2D index, for drawing it (`kiln render --mode cells`) and describing it.
struct IndexCell2 {
  format::Box2d box;
  std::uint32_t level = 0;  ///< 0 = the root
  std::uint32_t items = 0;  ///< what the cell lists: boundary edges, or points in a bucket
};

/// Point in polygon over a 2D polygon layer. A point lies in a polygon when it is inside its
/// outer ring and outside its holes under the half-open boundary rule of docs/FORMAT.md, so
/// a point of a partition (counties) lies in exactly one of its polygons or in none. Feature
/// indices are the source's order.
class PolygonQueries {
 public:
  static constexpr std::uint32_t kNone = 0xFFFFFFFFu;
  virtual ~PolygonQueries() = default;
  /// The lowest feature index whose area contains `p`, or kNone.
  virtual std::uint32_t locate(const format::Double2& p) const = 0;
  /// locate for a batch: out[i] = locate(points[i]) for every i, on up to `threads` threads
  /// (0 = all cores), each thread answering whole runs of consecutive points through the
  /// structure's batch path; the answers never depend on the thread count. `out` must hold
  /// points.size() answers (throws std::invalid_argument otherwise).
  virtual void locate_many(std::span<const format::Double2> points, std::span<std::uint32_t> out,
                           unsigned threads) const = 0;
  /// The same, counting cells visited (nodes) and edges tested (primitive tests) into `cost`.
  virtual std::uint32_t locate_counting(const format::Double2& p, Cost& cost) const = 0;
  /// Every feature containing `p`, ascending, into `out` (cleared first).
  virtual void locate_all(const format::Double2& p, std::vector<std::uint32_t>& out) const = 0;
  /// Every feature whose area (interior or boundary) meets the closed box, ascending.
  virtual void features_in_box(const format::Box2d& box, std::vector<std::uint32_t>& out) const = 0;
  /// The index's cells, leaves only, in storage order.
  virtual void cells(std::vector<IndexCell2>& out) const = 0;
};

/// A 2D point found by a neighbour query: its index in the point table's points and its
/// squared Euclidean distance in the table's coordinates.
struct Neighbor2 {
  double distance_squared = 0;
  std::uint32_t index = 0;
  friend bool operator==(const Neighbor2&, const Neighbor2&) = default;
};

/// Range and neighbour queries over a 2D point table; indices are into its points (the CLI
/// maps them to rows). Results are sorted as a brute-force scan sorts them.
class Point2Queries {
 public:
  virtual ~Point2Queries() = default;
  /// Every point inside the closed box, ascending index, into `out` (cleared first).
  virtual void range(const format::Box2d& box, std::vector<std::uint32_t>& out) const = 0;
  /// The same, counting nodes visited and points tested into `cost` (for heatmaps).
  virtual void range_counting(const format::Box2d& box, std::vector<std::uint32_t>& out,
                              Cost& cost) const = 0;
  /// The min(k, point count) nearest by (distance, index), k = out.size(); returns how many.
  virtual std::size_t nearest(const format::Double2& q, std::span<Neighbor2> out) const = 0;
  /// Every point with squared distance <= radius^2, by (distance, index), into `out`.
  virtual void within_radius(const format::Double2& q, double radius,
                             std::vector<Neighbor2>& out) const = 0;
  /// The index's leaf cells, in storage order.
  virtual void cells(std::vector<IndexCell2>& out) const = 0;
};

/// Issue 18: which events an aggregate query covers. Every field is optional (absent: all).
struct EventSelection {
  /// [min_lon, min_lat, max_lon, max_lat], snapped outward to the quadtree's finest cells.
  std::optional<format::Box2d> box;
  std::optional<std::array<std::uint32_t, 3>> tile;  ///< z, x, y (Web-Mercator, y south)
  /// [t0, t1) in Unix seconds, snapped outward to whole time bins.
  std::optional<std::array<std::int64_t, 2>> time;
  /// category name -> labels to keep (an unknown label matches nothing).
  std::vector<std::pair<std::string, std::vector<std::string>>> where;
};

/// What a selection became once snapped: the box of the covered finest cells and the time
/// interval of the covered bins.
struct EventSnap {
  format::Box2d box;
  std::int64_t t0 = 0, t1 = 0;
};

struct EventTileCount {
  std::uint32_t z = 0, x = 0, y = 0;
  std::uint64_t count = 0;
};

struct EventLabelCount {
  std::string label;
  std::uint64_t count = 0;
};

/// Aggregate queries over an event table (the nanocube). Bad requests (an unknown category, a
/// zoom past the finest level, a series bin that is not a whole number of the time bin) throw
/// std::invalid_argument with one line.
class EventQueries {
 public:
  virtual ~EventQueries() = default;
  /// The finest quadtree level (deepest tile zoom) and the time bin in seconds.
  virtual std::uint32_t finest_level() const = 0;
  virtual std::int64_t time_bin() const = 0;
  virtual EventSnap snap(const EventSelection& selection) const = 0;
  virtual std::uint64_t count(const EventSelection& selection) const = 0;
  /// Counts per bin of `bin_seconds` from the snapped t0 (the last bin may be shorter), every
  /// bin listed, zero or not: (bin start in Unix seconds, count).
  virtual std::vector<std::pair<std::int64_t, std::uint64_t>> series(
      const EventSelection& selection, std::int64_t bin_seconds) const = 0;
  /// Counts per tile at `zoom` of the selected events, tiles with none left out, sorted by x, y.
  virtual std::vector<EventTileCount> tiles(const EventSelection& selection,
                                            std::uint32_t zoom) const = 0;
  /// The `k` labels of category `by` with the largest counts (> 0), ties broken by label.
  virtual std::vector<EventLabelCount> topk(const EventSelection& selection, std::string_view by,
                                            std::size_t k) const = 0;
};

/// An opened, validated structure: the capabilities it has (nullptr for those it lacks).
/// Borrows the Blob it was opened from, which must outlive it.
class StructureView {
 public:
  virtual ~StructureView() = default;
  virtual const RayQueries* rays() const { return nullptr; }
  virtual const SurfaceQueries* surface() const { return nullptr; }
  virtual const NeighborQueries* neighbors() const { return nullptr; }
  virtual const OccupancyQueries* occupancy() const { return nullptr; }
  virtual const PolygonQueries* polygons() const { return nullptr; }
  virtual const Point2Queries* points2() const { return nullptr; }
  virtual const EventQueries* events() const { return nullptr; }  ///< issue 18
};

}  // namespace kiln
