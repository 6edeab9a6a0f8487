#include "kiln/tools/query_command.hpp"

#include <cmath>
#include <cstring>
#include <iostream>
#include <vector>

#include "kiln/runtime/atomic_file.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/esvo.hpp"
#include "kiln/runtime/kdtree.hpp"
#include "kiln/runtime/mapped_file.hpp"
#include "kiln/runtime/parallel.hpp"
#include "kiln/runtime/point_tree.hpp"
#include "kiln/runtime/proximity.hpp"
#include "kiln/runtime/voxel_dag.hpp"

namespace kiln {

namespace {

constexpr std::size_t kBatch = 1024;

template <class T>
void append_pod(std::vector<std::byte>& out, const T& value) {
  const auto* p = reinterpret_cast<const std::byte*>(&value);
  out.insert(out.end(), p, p + sizeof(T));
}

// What a query runs on: triangles (closest, inside, box), points (knn, radius) or voxels
// (occupied).
enum class Need { kSurface, kPoints, kVoxels };

// The structure a query runs on: the one --accel names, else the first BVH, else the first k-d
// tree (surface queries), the first point tree (knn, radius), or the first ESVO or DAG
// (occupied).
const schema::Acceleration& pick_structure(const Blob& blob, const QueryArgs& args, Need need) {
  const auto* accels = blob.manifest().accelerations();
  const bool points = need == Need::kPoints;
  const char* wanted = points ? "a point k-d tree (build with --accel points)"
                       : need == Need::kVoxels
                           ? "an ESVO or a voxel DAG (build with --accel esvo or dag)"
                           : "a BVH or k-d tree (build with --accel bvh, sbvh or kdtree)";
  auto first = [&](auto accepts) -> const schema::Acceleration* {
    if (accels)
      for (const auto* a : *accels)
        if (accepts(*a)) return a;
    return nullptr;
  };
  auto fits = [&](const schema::Acceleration& a) {
    if (need == Need::kVoxels) return a.esvo() != nullptr || a.dag() != nullptr;
    return points ? a.points() != nullptr : (a.bvh() != nullptr || a.kdtree() != nullptr);
  };
  if (!args.accel.empty()) {
    const auto* named = blob.acceleration(args.accel);
    if (named == nullptr) throw BlobError(blob.name() + ": has no structure '" + args.accel + "'");
    if (!fits(*named))
      throw BlobError(blob.name() + ": --op " + args.op + " needs " + wanted + ", and '" +
                      args.accel + "' is not one");
    return *named;
  }
  // A surface query prefers a BVH (the faster closest-point walk), else any structure that fits.
  const auto* found =
      need == Need::kSurface ? first([](const auto& a) { return a.bvh() != nullptr; }) : nullptr;
  if (found == nullptr) found = first(fits);
  if (found == nullptr) throw BlobError(blob.name() + ": holds no " + wanted);
  return *found;
}

// Query i's point (or a box's corner at offset k) in an input of `stride` floats per query.
format::Float3 point_at(const float* floats, std::size_t i, std::size_t stride, std::size_t k) {
  const float* f = floats + i * stride + k;
  return {f[0], f[1], f[2]};
}

// Runs `answer(i, bytes)` for every query in parallel batches and concatenates the bytes in
// query order, so the output does not depend on the thread count.
template <class Answer>
std::vector<std::byte> answer_all(std::size_t count, unsigned threads, Answer answer) {
  const std::size_t batches = (count + kBatch - 1) / kBatch;
  std::vector<std::vector<std::byte>> parts(batches);
  parallel_for(batches, threads, [&](std::size_t b) {
    for (std::size_t i = b * kBatch; i < std::min(count, (b + 1) * kBatch); ++i)
      answer(i, parts[b]);
  });
  std::vector<std::byte> out;
  for (const auto& part : parts) out.insert(out.end(), part.begin(), part.end());
  return out;
}

// closest, inside and box: the same code on a BVH or a k-d tree.
template <class Tree>
std::vector<std::byte> surface_queries(const Tree& tree, const Blob& blob, const QueryArgs& args,
                                       const float* floats, std::size_t count) {
  if (args.op == "closest")
    return answer_all(count, args.threads, [&](std::size_t i, std::vector<std::byte>& bytes) {
      const ClosestPoint c = closest_point(tree, point_at(floats, i, 3, 0), args.max_distance);
      append_pod(bytes, c.distance);
      append_pod(bytes, c.prim);
      append_pod(bytes, c.point);
    });
  if (args.op == "inside") {
    if (!blob.manifest().scene()->closed())
      std::cerr << "kiln query: warning: " << args.blob
                << " is not a closed mesh; inside answers are a best guess\n";
    return answer_all(count, args.threads, [&](std::size_t i, std::vector<std::byte>& bytes) {
      append_pod(bytes, std::uint8_t(point_inside(tree, point_at(floats, i, 3, 0)) ? 1 : 0));
    });
  }
  return answer_all(count, args.threads, [&](std::size_t i, std::vector<std::byte>& bytes) {
    std::vector<std::uint32_t> ids;
    triangles_in_box(tree, point_at(floats, i, 6, 0), point_at(floats, i, 6, 3), ids);
    append_pod(bytes, std::uint32_t(ids.size()));
    for (const auto id : ids) append_pod(bytes, id);
  });
}

// knn: K records per query, padded with (0xFFFFFFFF, +inf) when the tree holds fewer points;
// radius: a count, then the ids by distance.
std::vector<std::byte> point_queries(const PointTreeView& tree, const QueryArgs& args,
                                     const float* floats, std::size_t count) {
  if (args.op == "knn")
    return answer_all(count, args.threads, [&](std::size_t i, std::vector<std::byte>& bytes) {
      std::vector<Neighbor> found(args.k, Neighbor{kNoHit, INFINITY});
      tree.nearest(point_at(floats, i, 3, 0), found);
      for (const Neighbor& n : found) append_pod(bytes, n);
    });
  return answer_all(count, args.threads, [&](std::size_t i, std::vector<std::byte>& bytes) {
    std::vector<Neighbor> found;
    tree.within_radius(point_at(floats, i, 3, 0), args.radius, found);
    append_pod(bytes, std::uint32_t(found.size()));
    for (const Neighbor& n : found) append_pod(bytes, n.id);
  });
}

// occupied: 1 when the point lies in a leaf's region of the ESVO (cube cut by its contours) or in
// a set voxel of the DAG.
std::vector<std::byte> voxel_queries(const Blob& blob, const schema::Acceleration& structure,
                                     const QueryArgs& args, const float* floats,
                                     std::size_t count) {
  const std::string accel = structure.kind()->str();
  auto answer = [&](const auto& view) {
    return answer_all(count, args.threads, [&](std::size_t i, std::vector<std::byte>& bytes) {
      append_pod(bytes, std::uint8_t(view.occupied(point_at(floats, i, 3, 0)) ? 1 : 0));
    });
  };
  if (structure.esvo() != nullptr) return answer(EsvoView::from_blob(blob, accel));
  return answer(VoxelDagView::from_blob(blob, accel));
}

}  // namespace

int run_query(const QueryArgs& args) {
  try {
    const bool points = args.op == "knn" || args.op == "radius";
    const Need need = points                  ? Need::kPoints
                      : args.op == "occupied" ? Need::kVoxels
                                              : Need::kSurface;
    if (need == Need::kSurface && args.op != "closest" && args.op != "inside" && args.op != "box")
      throw std::runtime_error("unknown --op " + args.op);
    const Blob blob = Blob::open_file(args.blob);
    const schema::Acceleration& structure = pick_structure(blob, args, need);
    const std::string accel = structure.kind()->str();
    const MappedFile input(args.in);
    const std::size_t stride = args.op == "box" ? 24 : 12;
    if (input.bytes().size() % stride != 0)
      throw std::runtime_error(args.in + ": size " + std::to_string(input.bytes().size()) +
                               " is not a multiple of " + std::to_string(stride) + " bytes (" +
                               (stride == 24 ? "float32 x 6 per box" : "float32 x 3 per point") +
                               ")");
    const std::size_t count = input.bytes().size() / stride;
    // A mapping is page-aligned, so the floats are aligned too.
    const auto* floats = reinterpret_cast<const float*>(input.bytes().data());
    std::vector<std::byte> out;
    if (need == Need::kVoxels)
      out = voxel_queries(blob, structure, args, floats, count);
    else if (points)
      out = point_queries(PointTreeView::from_blob(blob, accel), args, floats, count);
    else if (structure.bvh() != nullptr)
      out = surface_queries(BvhView::from_blob(blob, accel), blob, args, floats, count);
    else
      out = surface_queries(KdTreeView::from_blob(blob, accel), blob, args, floats, count);
    write_file_atomically(args.out, out);
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "kiln query: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace kiln
