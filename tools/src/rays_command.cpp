// `kiln rays`: a reproducible RAYS file for a mesh or a blob. Diffuse and shadow rays start at
// primary hits, found with the blob's first triangle ray structure, else with one compiled in
// memory (the compiler's default ray structure).
#include <cstdio>
#include <cstring>
#include <iostream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "commands.hpp"
#include "kiln/compiler/build.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/compiler/structure_builder.hpp"
#include "kiln/formats/container.hpp"
#include "kiln/runtime/aligned_buffer.hpp"
#include "kiln/runtime/atomic_file.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "kiln/tools/ray_generator.hpp"
#include "kiln/tools/render.hpp"

namespace kiln::cli {

namespace {

struct RaysArgs {
  std::string input;  // a mesh or a .kiln blob
  std::string kind = "primary";
  std::uint64_t count = 100000;
  std::uint64_t seed = 1;
  std::string out;
  unsigned threads = 0;
  std::string camera;  // empty: frame the bounds
};

bool looks_like_blob(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) return false;
  unsigned char id[12] = {};
  const bool ok = std::fread(id, 1, 12, f) == 12;
  std::fclose(f);
  return ok && std::memcmp(id, format::kIdentifier.data(), 12) == 0;
}

std::vector<Ray> generate(const RaysArgs& args, const RayQueries& rays,
                          std::span<const format::Float3> positions,
                          std::span<const format::Triangle> triangles,
                          const format::Box3f& bounds) {
  const RayKind kind = args.kind == "primary"   ? RayKind::kPrimary
                       : args.kind == "diffuse" ? RayKind::kDiffuse
                                                : RayKind::kShadow;
  const RayScene scene{rays, positions, triangles, bounds.min, bounds.max};
  if (args.camera.empty()) return generate_rays(scene, kind, args.count, args.seed, args.threads);
  std::string error;
  const std::optional<render::Camera> c = render::parse_camera(args.camera, error);
  if (!c) throw std::invalid_argument("--camera: " + error);
  return generate_rays(scene, RayCamera{c->eye, c->target, c->fov_degrees}, kind, args.count,
                       args.seed, args.threads);
}

// The compiler's default ray structure: the first registered kind built over triangles.
const StructureBuilder& default_ray_builder() {
  for (const StructureBuilder* builder : structure_builders())
    if (builder->consumes == InputKind::kTriangles) return *builder;
  throw std::runtime_error("no structure kind is built over triangles");
}

// Compiles the scene with the default ray structure into a blob in memory, and generates the
// rays with it.
std::vector<Ray> generate_compiled(const RaysArgs& args, const Scene& scene) {
  const StructureBuilder& builder = default_ray_builder();
  BuildOptions options;
  options.structures.push_back(resolve_structure_request(builder.kind, {}));
  options.threads = args.threads;
  const std::vector<std::byte> bytes = compile_blob(scene, options);
  AlignedBuffer aligned(bytes.size(), 16);
  std::memcpy(aligned.data(), bytes.data(), bytes.size());
  const Blob blob = Blob::open_memory(aligned.bytes(), args.input + " (compiled in memory)");
  const auto view = open_structure(blob, builder.kind);
  if (view->rays() == nullptr) blob.fail("'" + builder.kind + "' does not trace rays");
  return generate(args, *view->rays(), scene.positions, scene.triangles,
                  {scene.bounds.min, scene.bounds.max});
}

// The blob's triangle scene as the compiler holds one.
Scene scene_of(const Blob& blob) {
  Scene scene;
  scene.positions.assign(blob.positions().begin(), blob.positions().end());
  scene.triangles.assign(blob.triangles().begin(), blob.triangles().end());
  scene.triangle_mesh.assign(blob.triangle_mesh_ids().begin(), blob.triangle_mesh_ids().end());
  for (std::size_t i = 0; i < blob.mesh_count(); ++i) {
    const MeshInfo m = blob.mesh(i);
    scene.meshes.push_back({m.name, m.source_file, m.first_triangle, m.triangle_count,
                            m.first_vertex, m.vertex_count});
  }
  for (const SourceInfo& s : blob.sources()) scene.sources.push_back({s.path, s.size, s.xxh3});
  scene.bounds = {blob.input().bounds.min, blob.input().bounds.max};
  return scene;
}

std::vector<Ray> generate_from_blob(const RaysArgs& args) {
  const Blob blob = Blob::open_file(args.input);
  if (blob.input().kind != InputKind::kTriangles)
    blob.fail("holds no triangles to aim rays at (its input is a " +
              std::string(input_kind_name(blob.input().kind)) + ")");
  for (const StructureInfo& info : blob.structures()) {
    const auto view = open_structure(blob, info.name);
    if (view->rays() != nullptr && view->rays()->record_size() == sizeof(Hit))
      return generate(args, *view->rays(), blob.positions(), blob.triangles(), blob.input().bounds);
  }
  return generate_compiled(args, scene_of(blob));
}

int run_rays(const RaysArgs& args) {
  try {
    const std::vector<Ray> rays =
        looks_like_blob(args.input)
            ? generate_from_blob(args)
            : generate_compiled(args, import_scene({args.input}, args.threads));
    write_file_atomically(args.out, std::as_bytes(std::span<const Ray>(rays)));
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "kiln rays: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace

Command add_rays_command(CLI::App& app) {
  auto args = std::make_shared<RaysArgs>();
  auto* command =
      app.add_subcommand("rays", "Generate a reproducible RAYS file for a mesh or blob");
  command->add_option("input", args->input, "A mesh file or a .kiln blob of triangles")->required();
  command->add_option("--kind", args->kind, "primary, diffuse or shadow")
      ->check(CLI::IsMember({"primary", "diffuse", "shadow"}))
      ->capture_default_str();
  command->add_option("--count", args->count, "Number of rays")
      ->check(CLI::Range(std::uint64_t{1}, std::uint64_t{1} << 28))
      ->capture_default_str();
  command->add_option("--seed", args->seed, "Random seed")->capture_default_str();
  command->add_option("--camera", args->camera,
                      "Primary rays from EX,EY,EZ,TX,TY,TZ,FOV (eye, target, vertical field of "
                      "view in degrees; as kiln render), e.g. inside a scene; default: frame the "
                      "bounds");
  command->add_option("-o,--output", args->out, "RAYS file to write")->required();
  add_threads_option(command, args->threads,
                     "Worker threads (0 = all cores); never changes the output");
  return {command, [args] { return run_rays(*args); }};
}

}  // namespace kiln::cli
