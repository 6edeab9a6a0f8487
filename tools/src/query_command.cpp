// `kiln query`: closest point, inside, box, kNN, radius and occupancy queries from a file of
// 3D positions or boxes, answered by whichever structure of the blob has the capability.
#include <cmath>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "commands.hpp"
#include "kiln/runtime/atomic_file.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/mapped_file.hpp"
#include "kiln/runtime/parallel.hpp"
#include "kiln/tools/query_json.hpp"
#include "kiln/tools/structure_choice.hpp"
#include "query_events.hpp"
#include "query_points2d.hpp"
#include "query_polygon.hpp"

namespace kiln::cli {

namespace {

constexpr std::size_t kBatch = 1024;

struct QueryArgs {
  std::string blob, op, in, out, accel;
  PolygonQueryArgs polygon;  // --op polygon, polygons-in-box (query_polygon.cpp)
  float max_distance = std::numeric_limits<float>::infinity();
  unsigned k = 1;
  double radius = 0;
  unsigned threads = 0;
};

// The query file: `count` queries of `stride` floats each (3 per point, 6 per box).
struct Queries {
  const float* floats = nullptr;
  std::size_t stride = 3, count = 0;
  // Query i's point (or a box's corner at offset k).
  format::Float3 at(std::size_t i, std::size_t k = 0) const {
    const float* f = floats + i * stride + k;
    return {f[0], f[1], f[2]};
  }
};

template <class T>
void append_pod(std::vector<std::byte>& out, const T& value) {
  const auto* p = reinterpret_cast<const std::byte*>(&value);
  out.insert(out.end(), p, p + sizeof(T));
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

// closest: distance, triangle, point; inside: one byte; box: a count, then the triangle ids.
std::vector<std::byte> surface_answers(const SurfaceQueries& s, const Blob& blob,
                                       const QueryArgs& args, const Queries& q) {
  if (args.op == "closest")
    return answer_all(q.count, args.threads, [&](std::size_t i, std::vector<std::byte>& bytes) {
      const ClosestPoint c = s.closest_point(q.at(i), args.max_distance);
      append_pod(bytes, c.distance);
      append_pod(bytes, c.prim);
      append_pod(bytes, c.point);
    });
  if (args.op == "inside") {
    if (!blob.input().closed)
      std::cerr << "kiln query: warning: " << args.blob
                << " is not a closed mesh; inside answers are a best guess\n";
    return answer_all(q.count, args.threads, [&](std::size_t i, std::vector<std::byte>& bytes) {
      append_pod(bytes, std::uint8_t(s.inside(q.at(i)) ? 1 : 0));
    });
  }
  return answer_all(q.count, args.threads, [&](std::size_t i, std::vector<std::byte>& bytes) {
    std::vector<std::uint32_t> ids;
    s.triangles_in_box(q.at(i), q.at(i, 3), ids);
    append_pod(bytes, std::uint32_t(ids.size()));
    for (const auto id : ids) append_pod(bytes, id);
  });
}

// knn: K records per query, padded with (0xFFFFFFFF, +inf) when there are fewer; radius: a
// count, then the ids by distance.
std::vector<std::byte> neighbor_answers(const NeighborQueries& n, const QueryArgs& args,
                                        const Queries& q) {
  if (args.op == "knn")
    return answer_all(q.count, args.threads, [&](std::size_t i, std::vector<std::byte>& bytes) {
      std::vector<Neighbor> found(args.k, Neighbor{kNoHit, INFINITY});
      n.nearest(q.at(i), found);
      for (const Neighbor& neighbor : found) append_pod(bytes, neighbor);
    });
  return answer_all(q.count, args.threads, [&](std::size_t i, std::vector<std::byte>& bytes) {
    std::vector<Neighbor> found;
    n.within_radius(q.at(i), float(args.radius), found);
    append_pod(bytes, std::uint32_t(found.size()));
    for (const Neighbor& neighbor : found) append_pod(bytes, neighbor.id);
  });
}

// occupied: 1 when the point lies in the structure's solid.
std::vector<std::byte> occupancy_answers(const OccupancyQueries& o, const QueryArgs& args,
                                         const Queries& q) {
  return answer_all(q.count, args.threads, [&](std::size_t i, std::vector<std::byte>& bytes) {
    append_pod(bytes, std::uint8_t(o.occupied(q.at(i)) ? 1 : 0));
  });
}

bool neighbor_op(const std::string& op) {
  return op == "knn" || op == "radius";
}

// The structure --op runs on: the one --accel names, else the first with the capability.
ChosenStructure choose_for(const Blob& blob, const QueryArgs& args) {
  if (neighbor_op(args.op))
    return choose_structure(blob, args.accel, &StructureView::neighbors,
                            "answer nearest-neighbour queries");
  if (args.op == "occupied")
    return choose_structure(blob, args.accel, &StructureView::occupancy,
                            "answer occupancy queries");
  return choose_structure(blob, args.accel, &StructureView::surface, "answer surface queries");
}

int run_query(const QueryArgs& args) {
  // Event ops always, 2D ops on a .jsonl file: JSON lines through answer_json_query, the code
  // path `kiln serve` answers POST /api/query with (query_json.cpp).
  if (is_event_op(args.op) || (is_json_op(args.op) && args.in.ends_with(".jsonl")))
    return run_json_query(args.blob, args.accel, args.op, args.in, args.out);
  if (is_polygon_op(args.op)) {
    PolygonQueryArgs p = args.polygon;
    p.blob = args.blob, p.op = args.op, p.in = args.in, p.out = args.out, p.accel = args.accel;
    p.threads = args.threads;
    return run_polygon_query(p);
  }
  try {
    const Blob blob = Blob::open_file(args.blob);
    const ChosenStructure chosen = choose_for(blob, args);
    const MappedFile input(args.in);
    const std::size_t stride = args.op == "box" ? 6 : 3;
    const std::size_t bytes = input.bytes().size();
    if (bytes % (stride * sizeof(float)) != 0)
      throw std::runtime_error(args.in + ": size " + std::to_string(bytes) +
                               " is not a multiple of " + std::to_string(stride * 4) + " bytes (" +
                               (stride == 6 ? "float32 x 6 per box" : "float32 x 3 per point") +
                               ")");
    // A mapping is page-aligned, so the floats are aligned too.
    const Queries queries{reinterpret_cast<const float*>(input.bytes().data()), stride,
                          bytes / (stride * sizeof(float))};
    const StructureView& view = *chosen.view;
    const std::vector<std::byte> out =
        neighbor_op(args.op)    ? neighbor_answers(*view.neighbors(), args, queries)
        : args.op == "occupied" ? occupancy_answers(*view.occupancy(), args, queries)
                                : surface_answers(*view.surface(), blob, args, queries);
    write_file_atomically(args.out, out);
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "kiln query: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace

Command add_query_command(CLI::App& app) {
  auto args = std::make_shared<QueryArgs>();
  auto* command = app.add_subcommand(
      "query", "Closest point, inside, box, knn, radius and occupied queries on a blob");
  command->add_option("blob", args->blob, "The .kiln file")->required();
  command
      ->add_option("--op", args->op,
                   "closest, inside, box (surface queries); knn, radius (nearest neighbours among "
                   "the vertices); occupied (voxel structures); polygon, polygons-in-box (2D "
                   "polygon layers); range, knn2d, radius2d (2D point tables: CSV rows out); "
                   "count, series, tiles, topk (event tables: JSON lines)")
      ->check(CLI::IsMember({"closest", "inside", "box", "knn", "radius", "occupied", "polygon",
                             "polygons-in-box", "range", "knn2d", "radius2d", "count", "series",
                             "tiles", "topk"}))
      ->required();
  command
      ->add_option("--in", args->in,
                   "Queries: float32 x 3 per point, x 6 per box (min, max); polygon: CSV (.csv) "
                   "or float64 x 2 per point; polygons-in-box and range: CSV rows "
                   "min_x,min_y,max_x,max_y or float64 x 4 per box; knn2d, radius2d: CSV rows "
                   "x,y or float64 x 2 (CSV headers optional); a .jsonl file: one JSON query per "
                   "line for any 2D or event op (docs/SERVE.md), JSON answers out")
      ->required();
  command
      ->add_option(
          "--out", args->out,
          "Answers (docs/FORMAT.md); polygon: CSV in gives CSV (the input's columns, then "
          "polygon_index (-1: none), polygon_id, polygon_name), binary in gives uint32 per "
          "point (0xFFFFFFFF: none); polygons-in-box: rows box_index,feature_index (CSV) "
          "or uint32 pairs; range: rows box_index,point_index; knn2d, radius2d: rows "
          "query_index,point_index,distance")
      ->required();
  command->add_option("--accel", args->accel,
                      "Structure to use, by name (default: the first that answers --op)");
  command->add_option("--max-distance", args->max_distance, "closest: ignore surfaces farther away")
      ->check(CLI::PositiveNumber);
  command->add_option("--k", args->k, "knn: neighbours per query")->check(CLI::Range(1u, 4096u));
  command->add_option("--radius", args->radius, "radius: search radius")
      ->check(CLI::NonNegativeNumber);
  add_polygon_query_options(command, args->polygon);
  add_threads_option(command, args->threads);
  return {command, [args] {
            if (is_points2d_op(args->op) && !args->in.ends_with(".jsonl"))
              return run_points2d_query({args->blob, args->op, args->in, args->out, args->accel,
                                         args->k, args->radius, args->threads});
            return run_query(*args);
          }};
}

}  // namespace kiln::cli
