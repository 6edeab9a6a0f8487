#include "kiln/compiler/build.hpp"

#include <chrono>
#include <stdexcept>

#include "accel_entry.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/formats/section_kinds.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/parallel.hpp"
#include "manifest_builder.hpp"

namespace kiln {

namespace {

AccelEntry make_accel_entry(const Scene& scene, const AccelRequest& request, unsigned threads) {
  if (request.kind == "bvh" || request.kind == "sbvh")
    return make_bvh_entry(scene, request, threads);
  if (request.kind == "kdtree") return make_kdtree_entry(scene, request, threads);
  if (request.kind == "points") return make_point_tree_entry(scene, request, threads);
  if (request.kind == "dag") return make_voxel_dag_entry(scene, request, threads);
  if (request.kind == "esvo") return make_esvo_entry(scene, request, threads);
  throw std::runtime_error("unknown acceleration structure '" + request.kind + "'");
}

template <class T>
std::span<const std::byte> as_bytes(const std::vector<T>& values) {
  return std::as_bytes(std::span<const T>(values));
}

}  // namespace

bool needs_triangles(const std::string& kind) {
  return kind != "points";
}

Scene import_scene(const std::vector<std::string>& inputs, unsigned threads,
                   const BuildProgress& progress) {
  std::vector<ImportedFile> files(inputs.size());
  if (progress) progress("import", 0, inputs.size());
  parallel_for(inputs.size(), threads, [&](std::size_t i) { files[i] = import_file(inputs[i]); });
  if (progress) progress("import", inputs.size(), inputs.size());
  FileAccesses accessed;
  for (const ImportedFile& file : files) {
    accessed.read.insert(accessed.read.end(), file.accessed.read.begin(), file.accessed.read.end());
    accessed.missing.insert(accessed.missing.end(), file.accessed.missing.begin(),
                            file.accessed.missing.end());
  }
  normalize_accesses(accessed);  // once: sorting per input would be quadratic in the inputs
  Scene scene = assemble_scene(std::move(files));
  scene.accessed = std::move(accessed);
  // An empty scene is almost surely a broken input; an asset pipeline should hear about it.
  if (scene.triangles.empty() && scene.positions.empty())
    throw ImportError(inputs.front() + (inputs.size() > 1 ? " (and the other inputs)" : "") +
                      ": no triangles left: all " + std::to_string(scene.input_triangle_count) +
                      " are degenerate (zero area or non-finite)");
  return scene;
}

std::vector<std::byte> compile_blob(const Scene& scene, const BuildOptions& options,
                                    std::vector<AccelReport>* reports) {
  if (scene.triangles.empty()) {
    const std::string what = scene.sources.empty() ? "the scene" : scene.sources.front().path;
    if (options.accels.empty())
      throw ImportError(what + ": has points but no triangles; a point cloud needs --accel points");
    for (const AccelRequest& request : options.accels)
      if (needs_triangles(request.kind))
        throw ImportError(what + ": has points but no triangles, so --accel " + request.kind +
                          " cannot be built (a point cloud takes --accel points alone)");
  }
  constexpr auto kRequired = std::uint16_t(format::SectionFlag::kRequired);
  std::vector<SectionPayload> sections;
  sections.push_back({});  // the manifest, filled in once the other indices are known
  auto add = [&](std::uint32_t kind, std::uint32_t element_size, std::uint64_t count,
                 std::span<const std::byte> bytes) {
    sections.push_back({kind, kRequired, element_size, count, bytes, true});
    return std::uint32_t(sections.size() - 1);
  };
  GeometrySectionIndices indices{};
  indices.positions = add(format::kSectionPositions, sizeof(format::Float3), scene.positions.size(),
                          as_bytes(scene.positions));
  indices.triangles = add(format::kSectionTriangles, sizeof(format::Triangle),
                          scene.triangles.size(), as_bytes(scene.triangles));
  indices.triangle_mesh = add(format::kSectionTriangleMesh, sizeof(std::uint32_t),
                              scene.triangle_mesh.size(), as_bytes(scene.triangle_mesh));
  indices.normals = scene.normals.empty() ? kNoSection
                                          : add(format::kSectionNormals, sizeof(format::Float3),
                                                scene.normals.size(), as_bytes(scene.normals));
  // Each structure is built in turn (each build is parallel inside) and kept alive until the
  // blob is serialised, since sections only borrow their bytes.
  std::vector<AccelEntry> entries;
  std::vector<std::vector<std::uint32_t>> entry_sections;
  for (const AccelRequest& request : options.accels) {
    const auto start = std::chrono::steady_clock::now();
    entries.push_back(make_accel_entry(scene, request, options.threads));
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (reports) reports->push_back({request.kind, entries.back().summary, seconds});
    auto& owned = entry_sections.emplace_back();
    for (const SectionPayload& section : entries.back().sections) {
      sections.push_back(section);
      owned.push_back(std::uint32_t(sections.size() - 1));
    }
  }
  const std::vector<std::byte> manifest =
      build_manifest(scene, options, indices, entries, entry_sections);
  sections[0] = {format::kSectionManifest, kRequired, 1, manifest.size(), manifest, false};
  return serialize_blob(sections, options.compression, options.threads);
}

}  // namespace kiln
