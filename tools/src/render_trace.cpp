// One counted closest-hit query per pixel, on whichever ray structure of the blob is asked for.
#include <cmath>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/esvo.hpp"
#include "kiln/runtime/kdtree.hpp"
#include "kiln/runtime/parallel.hpp"
#include "kiln/runtime/voxel_dag.hpp"
#include "kiln/tools/render.hpp"

namespace kiln::render {

namespace {

enum class Kind { kBvh, kKdTree, kDag, kEsvo, kNone };

Kind kind_of(const schema::Acceleration& a) {
  if (a.bvh() != nullptr) return Kind::kBvh;
  if (a.kdtree() != nullptr) return Kind::kKdTree;
  if (a.dag() != nullptr) return Kind::kDag;
  if (a.esvo() != nullptr) return Kind::kEsvo;
  return Kind::kNone;  // the point k-d tree: no rays
}

// `n` made unit length and turned against the ray (the side the camera sees); -dir when `n`
// is zero or not finite, so shading stays defined.
format::Float3 facing(format::Float3 n, const format::Float3& dir) {
  const float length = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
  if (!(length > 0) || !std::isfinite(length)) return {-dir.x, -dir.y, -dir.z};
  const float s = (n.x * dir.x + n.y * dir.y + n.z * dir.z > 0 ? -1.0f : 1.0f) / length;
  return {n.x * s, n.y * s, n.z * s};
}

// The geometric normal of stored triangle `prim`. Indices are checked here: a blob that was
// opened but never verified may hold any value.
format::Float3 triangle_normal(std::span<const format::Triangle> triangles,
                               std::span<const format::Float3> positions, std::uint32_t prim) {
  if (prim >= triangles.size()) return {0, 0, 0};
  const auto& tri = triangles[prim];
  for (const auto v : tri.v)
    if (v >= positions.size()) return {0, 0, 0};
  const auto& a = positions[tri.v[0]];
  const auto& b = positions[tri.v[1]];
  const auto& c = positions[tri.v[2]];
  const float e1[3] = {b.x - a.x, b.y - a.y, b.z - a.z};
  const float e2[3] = {c.x - a.x, c.y - a.y, c.z - a.z};
  return {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
          e1[0] * e2[1] - e1[1] * e2[0]};
}

// Rows are the parallel tasks: each writes only its own pixels, so the samples do not depend
// on the thread count. `cast(ray, sample)` fills one sample.
template <class Cast>
Samples trace_rows(const Camera& camera, Size size, unsigned threads, const Cast& cast) {
  Samples samples;
  samples.size = size;
  samples.pixels.resize(std::size_t(size.width) * size.height);
  const PixelRays rays(camera, size);
  parallel_for(size.height, threads, [&](std::size_t y) {
    for (std::uint32_t x = 0; x < size.width; ++x) {
      const Ray ray = rays(x, std::uint32_t(y));
      Sample& s = samples.pixels[y * size.width + x];
      cast(ray, s);
      if (s.hit) s.normal = facing(s.normal, ray.dir);
    }
  });
  return samples;
}

// A voxel hit's normal: the attached normal when the blob stores one (the mesh's own normal, what
// Laine & Karras shade with: a cube face or a contour plane alone makes blocky, speckled
// shading), else the entered face or the contour's plane.
format::Float3 voxel_normal(const VoxelHit& h) {
  if (h.normal[0] != 0 || h.normal[1] != 0 || h.normal[2] != 0)
    return {h.normal[0], h.normal[1], h.normal[2]};
  return {h.face_normal[0], h.face_normal[1], h.face_normal[2]};
}

// A triangle structure (BVH, SBVH, k-d tree): the hit triangle's geometric normal.
template <class View>
Samples trace_triangles(const Blob& blob, const View& view, const Camera& camera, Size size,
                        unsigned threads) {
  const auto triangles = blob.triangles();
  const auto positions = blob.positions();
  return trace_rows(camera, size, threads, [&](const Ray& ray, Sample& s) {
    typename View::Cost cost;
    const Hit h = view.intersect_counting(ray, cost);
    s.nodes = cost.nodes, s.tests = cost.triangles;
    if ((s.hit = h.prim != kNoHit))
      s.t = h.t, s.normal = triangle_normal(triangles, positions, h.prim);
  });
}

const VoxelHit& voxel_hit_of(const VoxelHit& hit) {
  return hit;
}
const VoxelHit& voxel_hit_of(const EsvoHit& hit) {
  return hit.hit;
}

// A voxel structure (DAG, ESVO): voxel tests count as the primitive tests.
template <class View>
Samples trace_voxels(const View& view, const Camera& camera, Size size, unsigned threads) {
  return trace_rows(camera, size, threads, [&](const Ray& ray, Sample& s) {
    typename View::Cost cost;
    const auto result = view.intersect_counting(ray, cost);
    const VoxelHit& h = voxel_hit_of(result);
    s.nodes = cost.nodes, s.tests = cost.voxels;
    if ((s.hit = h.hit())) s.t = h.t, s.normal = voxel_normal(h);
  });
}

}  // namespace

std::vector<std::string> ray_structures(const Blob& blob) {
  std::vector<std::string> names;
  if (const auto* accels = blob.manifest().accelerations())
    for (const auto* a : *accels)
      if (kind_of(*a) != Kind::kNone) names.push_back(a->kind()->str());
  return names;
}

std::string default_structure(const Blob& blob) {
  const auto names = ray_structures(blob);
  if (names.empty())
    throw BlobError(blob.name() +
                    ": holds no ray structure (build with --accel bvh, sbvh, kdtree, dag or esvo)");
  return names.front();
}

Samples trace_view(const Blob& blob, const std::string& accel, const Camera& camera, Size size,
                   unsigned threads) {
  const auto* structure = blob.acceleration(accel);
  if (structure == nullptr)
    throw BlobError(blob.name() + ": has no acceleration structure '" + accel + "'");
  switch (kind_of(*structure)) {
    case Kind::kBvh:
      return trace_triangles(blob, BvhView::from_blob(blob, accel), camera, size, threads);
    case Kind::kKdTree:
      return trace_triangles(blob, KdTreeView::from_blob(blob, accel), camera, size, threads);
    case Kind::kDag:
      return trace_voxels(VoxelDagView::from_blob(blob, accel), camera, size, threads);
    case Kind::kEsvo:
      return trace_voxels(EsvoView::from_blob(blob, accel), camera, size, threads);
    case Kind::kNone:
      break;
  }
  throw BlobError(blob.name() + ": '" + accel + "' does not trace rays");
}

CostSummary summarize(const Samples& samples) {
  CostSummary s;
  std::uint64_t nodes = 0, tests = 0, hits = 0;
  for (const Sample& p : samples.pixels) {
    nodes += p.nodes;
    tests += p.tests;
    hits += p.hit;
    s.max_cost = std::max(s.max_cost, p.cost());
  }
  const double n = samples.pixels.empty() ? 1.0 : double(samples.pixels.size());
  s.mean_nodes = double(nodes) / n;
  s.mean_tests = double(tests) / n;
  s.mean_cost = double(nodes + tests) / n;
  s.hit_fraction = double(hits) / n;
  return s;
}

}  // namespace kiln::render
