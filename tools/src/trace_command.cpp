#include "kiln/tools/trace_command.hpp"

#include <chrono>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <optional>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/runtime/atomic_file.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/bvh.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/esvo.hpp"
#include "kiln/runtime/kdtree.hpp"
#include "kiln/runtime/mapped_file.hpp"
#include "kiln/runtime/voxel_dag.hpp"
#include "kiln/tools/ray_generator.hpp"

namespace kiln {

namespace {

std::string default_accel(const Blob& blob) {
  const auto* accels = blob.manifest().accelerations();
  if (accels == nullptr || accels->size() == 0)
    throw BlobError(blob.name() + ": holds no acceleration structure (build with --accel)");
  return accels->Get(0)->kind()->str();
}

// Traces with whichever structure `accel` names.
void trace_with(const Blob& blob, const std::string& accel, std::span<const Ray> rays,
                std::span<Hit> hits, bool any_hit, unsigned threads) {
  const auto* a = blob.acceleration(accel);
  if (a == nullptr)
    throw BlobError(blob.name() + ": has no acceleration structure '" + accel + "'");
  if (a->kdtree() != nullptr)
    return trace_rays(KdTreeView::from_blob(blob, accel), rays, hits, any_hit, threads);
  if (a->bvh() != nullptr)
    return trace_rays(BvhView::from_blob(blob, accel), rays, hits, any_hit, threads);
  throw BlobError(blob.name() + ": '" + accel + "' does not trace rays");
}

// The DAG or the ESVO named `accel`, on the 40-byte voxel-hit record.
void trace_voxels(const Blob& blob, const std::string& accel, std::span<const Ray> rays,
                  std::span<VoxelHit> hits, bool any_hit, unsigned threads) {
  if (const auto* a = blob.acceleration(accel); a != nullptr && a->esvo() != nullptr)
    return trace_rays(EsvoView::from_blob(blob, accel), rays, hits, any_hit, threads);
  trace_rays(VoxelDagView::from_blob(blob, accel), rays, hits, any_hit, threads);
}

bool is_voxel_structure(const Blob& blob, const std::string& accel) {
  const auto* a = blob.acceleration(accel);
  return a != nullptr && (a->dag() != nullptr || a->esvo() != nullptr);
}

// The first BVH in the blob, if any.
std::string first_bvh(const Blob& blob) {
  if (const auto* accels = blob.manifest().accelerations())
    for (const auto* a : *accels)
      if (a->bvh() != nullptr) return a->kind()->str();
  return {};
}

bool looks_like_blob(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) return false;
  unsigned char id[12] = {};
  const bool ok = std::fread(id, 1, 12, f) == 12;
  std::fclose(f);
  return ok && std::memcmp(id, format::kIdentifier.data(), 12) == 0;
}

}  // namespace

int run_trace(const TraceArgs& args) {
  try {
    const Blob blob = Blob::open_file(args.blob);
    const std::string accel = args.accel.empty() ? default_accel(blob) : args.accel;
    const MappedFile rays_file(args.rays);
    const auto bytes = rays_file.bytes();
    if (bytes.size() % sizeof(Ray) != 0) {
      std::cerr << "kiln trace: " << args.rays << ": size " << bytes.size()
                << " is not a multiple of 32 bytes (8 float32 per ray)\n";
      return 1;
    }
    // The mapping is page-aligned, so the rays can be read in place.
    const std::span<const Ray> rays(reinterpret_cast<const Ray*>(bytes.data()),
                                    bytes.size() / sizeof(Ray));
    const auto start = std::chrono::steady_clock::now();
    std::size_t hit_count = 0;
    double seconds = 0;
    auto elapsed = [&] {
      return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    if (is_voxel_structure(blob, accel)) {
      // A voxel has no triangle id: voxel structures write the 40-byte voxel-hit record.
      std::vector<VoxelHit> hits(rays.size());
      trace_voxels(blob, accel, rays, hits, args.any_hit, args.threads);
      seconds = elapsed();
      write_file_atomically(args.out, std::as_bytes(std::span<const VoxelHit>(hits)));
      for (const auto& h : hits) hit_count += h.hit();
    } else {
      std::vector<Hit> hits(rays.size());
      trace_with(blob, accel, rays, hits, args.any_hit, args.threads);
      seconds = elapsed();
      write_file_atomically(args.out, std::as_bytes(std::span<const Hit>(hits)));
      for (const auto& h : hits) hit_count += h.prim != kNoHit;
    }
    std::fprintf(stderr, "kiln trace: %zu rays on %s, %zu hits, %.3f Mrays/s\n", rays.size(),
                 accel.c_str(), hit_count,
                 seconds > 0 ? double(rays.size()) / seconds * 1e-6 : 0.0);
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "kiln trace: " << e.what() << "\n";
    return 1;
  }
}

int run_rays(const RaysArgs& args) {
  try {
    const RayKind kind = args.kind == "primary"   ? RayKind::kPrimary
                         : args.kind == "diffuse" ? RayKind::kDiffuse
                                                  : RayKind::kShadow;
    std::vector<Ray> rays;
    auto generate = [&](const BvhView& bvh, std::span<const format::Float3> positions,
                        std::span<const format::Triangle> triangles, format::Float3 lo,
                        format::Float3 hi) {
      rays = generate_rays({bvh, positions, triangles, lo, hi}, kind, args.count, args.seed,
                           args.threads);
    };
    if (looks_like_blob(args.input)) {
      const Blob blob = Blob::open_file(args.input);
      const auto* b = blob.manifest().scene()->bounds();
      const format::Float3 lo{b->min().x(), b->min().y(), b->min().z()};
      const format::Float3 hi{b->max().x(), b->max().y(), b->max().z()};
      if (const std::string bvh = first_bvh(blob); !bvh.empty()) {
        generate(BvhView::from_blob(blob, bvh), blob.positions(), blob.triangles(), lo, hi);
      } else {  // primary hits need a BVH: build one over the blob's own triangles
        Scene scene;
        scene.positions.assign(blob.positions().begin(), blob.positions().end());
        scene.triangles.assign(blob.triangles().begin(), blob.triangles().end());
        scene.bounds = {lo, hi};
        BvhBuildOptions options;
        options.threads = args.threads;
        const FlatBvh flat = build_bvh(scene, options);
        generate(BvhView(flat.nodes, flat.triangles, flat.prim_ids), blob.positions(),
                 blob.triangles(), lo, hi);
      }
    } else {
      const Scene scene = import_scene({args.input}, args.threads);
      BvhBuildOptions options;
      options.threads = args.threads;
      const FlatBvh flat = build_bvh(scene, options);
      const BvhView bvh(flat.nodes, flat.triangles, flat.prim_ids);
      generate(bvh, scene.positions, scene.triangles, scene.bounds.min, scene.bounds.max);
    }
    write_file_atomically(args.out, std::as_bytes(std::span<const Ray>(rays)));
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "kiln rays: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace kiln
