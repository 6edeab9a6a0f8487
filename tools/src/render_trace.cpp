// One counted closest-hit query per pixel, on whichever ray structure of the blob is asked for.
#include <cmath>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/parallel.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "kiln/tools/render.hpp"
#include "kiln/tools/structure_choice.hpp"

namespace kiln::render {

namespace {

// `n` made unit length and turned against the ray (the side the camera sees); -dir when `n`
// is zero or not finite, so shading stays defined.
format::Float3 facing(format::Float3 n, const format::Float3& dir) {
  const float length = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
  if (!(length > 0) || !std::isfinite(length)) return {-dir.x, -dir.y, -dir.z};
  const float s = (n.x * dir.x + n.y * dir.y + n.z * dir.z > 0 ? -1.0f : 1.0f) / length;
  return {n.x * s, n.y * s, n.z * s};
}

}  // namespace

std::vector<std::string> ray_structures(const Blob& blob) {
  std::vector<std::string> names;
  for (const StructureInfo& info : blob.structures())
    if (open_structure(blob, info.name)->rays() != nullptr) names.push_back(info.name);
  return names;
}

std::string default_structure(const Blob& blob) {
  return choose_structure(blob, "", &StructureView::rays, "trace rays").name;
}

// Rows are the parallel tasks: each writes only its own pixels, so the samples do not depend
// on the thread count.
Samples trace_view(const RayQueries& rays, const Camera& camera, Size size, unsigned threads) {
  Samples samples;
  samples.size = size;
  samples.pixels.resize(std::size_t(size.width) * size.height);
  const PixelRays pixel_rays(camera, size);
  parallel_for(size.height, threads, [&](std::size_t y) {
    for (std::uint32_t x = 0; x < size.width; ++x) {
      const Ray ray = pixel_rays(x, std::uint32_t(y));
      Sample& s = samples.pixels[y * size.width + x];
      Cost cost;
      const SurfaceHit h = rays.intersect_counting(ray, cost);
      s.nodes = cost.nodes, s.tests = cost.tests;
      if ((s.hit = h.hit.hit())) s.t = h.hit.t, s.normal = facing(h.normal, ray.dir);
    }
  });
  return samples;
}

Samples trace_view(const Blob& blob, const std::string& accel, const Camera& camera, Size size,
                   unsigned threads) {
  const auto chosen = choose_structure(blob, accel, &StructureView::rays, "trace rays");
  return trace_view(*chosen.view->rays(), camera, size, threads);
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
