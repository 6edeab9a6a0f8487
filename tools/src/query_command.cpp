#include "kiln/tools/query_command.hpp"

#include <cstring>
#include <iostream>
#include <vector>

#include "kiln/compiler/atomic_file.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/mapped_file.hpp"
#include "kiln/runtime/parallel.hpp"
#include "kiln/runtime/proximity.hpp"

namespace kiln {

namespace {

constexpr std::size_t kBatch = 1024;

template <class T>
void append_pod(std::vector<std::byte>& out, const T& value) {
  const auto* p = reinterpret_cast<const std::byte*>(&value);
  out.insert(out.end(), p, p + sizeof(T));
}

std::string first_bvh(const Blob& blob) {
  if (const auto* accels = blob.manifest().accelerations())
    for (const auto* a : *accels)
      if (a->bvh() != nullptr) return a->kind()->str();
  throw BlobError(blob.name() + ": holds no BVH (build with --accel bvh or --accel sbvh)");
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

}  // namespace

int run_query(const QueryArgs& args) {
  try {
    if (args.op == "knn" || args.op == "radius")
      throw std::runtime_error(
          "--op " + args.op +
          " needs a point k-d tree (--accel points), which is not implemented yet");
    const Blob blob = Blob::open_file(args.blob);
    const BvhView bvh = BvhView::from_blob(blob, args.accel.empty() ? first_bvh(blob) : args.accel);
    const MappedFile input(args.in);
    const std::size_t stride = args.op == "box" ? 24 : 12;
    if (input.bytes().size() % stride != 0)
      throw std::runtime_error(args.in + ": size " + std::to_string(input.bytes().size()) +
                               " is not a multiple of " + std::to_string(stride) + " bytes (" +
                               (stride == 24 ? "float32 x 6 per box" : "float32 x 3 per point") +
                               ")");
    const std::size_t count = input.bytes().size() / stride;
    const auto* floats = reinterpret_cast<const float*>(input.bytes().data());
    auto point = [&](std::size_t i, std::size_t k) {
      return format::Float3{floats[i * stride / 4 + k], floats[i * stride / 4 + k + 1],
                            floats[i * stride / 4 + k + 2]};
    };
    std::vector<std::byte> out;
    if (args.op == "closest") {
      out = answer_all(count, args.threads, [&](std::size_t i, std::vector<std::byte>& bytes) {
        const ClosestPoint c = closest_point(bvh, point(i, 0), args.max_distance);
        append_pod(bytes, c.distance);
        append_pod(bytes, c.prim);
        append_pod(bytes, c.point);
      });
    } else if (args.op == "inside") {
      if (!blob.manifest().scene()->closed())
        std::cerr << "kiln query: warning: " << args.blob
                  << " is not a closed mesh; inside answers are a best guess\n";
      out = answer_all(count, args.threads, [&](std::size_t i, std::vector<std::byte>& bytes) {
        append_pod(bytes, std::uint8_t(point_inside(bvh, point(i, 0)) ? 1 : 0));
      });
    } else if (args.op == "box") {
      out = answer_all(count, args.threads, [&](std::size_t i, std::vector<std::byte>& bytes) {
        std::vector<std::uint32_t> ids;
        triangles_in_box(bvh, point(i, 0), point(i, 3), ids);
        append_pod(bytes, std::uint32_t(ids.size()));
        for (const auto id : ids) append_pod(bytes, id);
      });
    } else {
      throw std::runtime_error("unknown --op " + args.op);
    }
    write_file_atomically(args.out, out);
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "kiln query: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace kiln
