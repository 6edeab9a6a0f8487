#include "kiln/compiler/build.hpp"

#include <chrono>
#include <stdexcept>

#include "event_table_sections.hpp"
#include "geo_input.hpp"
#include "kiln/compiler/advise.hpp"
#include "kiln/compiler/file_accesses.hpp"
#include "kiln/compiler/geo_import.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/compiler/import_events.hpp"
#include "kiln/formats/section_kinds.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/parallel.hpp"
#include "manifest_builder.hpp"

namespace kiln {

namespace {

template <class T>
std::span<const std::byte> as_bytes(const std::vector<T>& values) {
  return std::as_bytes(std::span<const T>(values));
}

// "--accel a or --accel b": every kind that a blob of this input can hold.
std::string kinds_for(InputKind input) {
  std::string text;
  for (const StructureBuilder* builder : structure_builders())
    if (input_provides(input, builder->consumes))
      text += (text.empty() ? "--accel " : " or --accel ") + builder->kind;
  return text;
}

// Refuses duplicate names and structures the input cannot feed, each with one line.
void check_requests(const Scene& scene, const BuildOptions& options) {
  const auto& requests = options.structures;
  for (std::size_t i = 0; i < requests.size(); ++i)
    for (std::size_t j = 0; j < i; ++j)
      if (requests[i].name == requests[j].name)
        throw ImportError("two structures named '" + requests[i].name +
                          "' (give one another name: --accel KIND:name=NAME)");
  const InputKind input = input_kind_of(scene);
  if (input == InputKind::kTriangles) return;
  const std::string what = scene.sources.empty() ? "the scene" : scene.sources.front().path;
  // Every other input kind lacks triangles, and triangles are what most structures consume.
  const std::string is = what + ": is a " + std::string(input_kind_name(input)) + " (no triangles)";
  // A 2D layer alone is a map (kiln render draws it); a 3D point set alone is likely a mistake.
  if (requests.empty() && input == InputKind::kPoint3)
    throw ImportError(is + "; it needs " + kinds_for(input));
  for (const StructureRequest& request : requests) {
    const StructureBuilder* builder = find_structure_builder(request.kind);
    if (!builder) throw std::invalid_argument("unknown structure kind '" + request.kind + "'");
    if (!input_provides(input, builder->consumes))
      throw ImportError(is + ", so --accel " + request.kind +
                        " cannot be built (this input takes " + kinds_for(input) + ")");
  }
}

// Appends the input's sections (after the manifest's slot) and says where they went.
InputSectionIndices add_input_sections(const Scene& scene, std::vector<SectionPayload>& sections) {
  constexpr auto kRequired = std::uint16_t(format::SectionFlag::kRequired);
  auto add = [&](std::uint32_t kind, std::uint32_t element_size, std::uint64_t count,
                 std::span<const std::byte> bytes) {
    sections.push_back({kind, kRequired, element_size, count, bytes, true});
    return std::uint32_t(sections.size() - 1);
  };
  InputSectionIndices indices;
  if (scene.events) {  // issue 18: an event table's columns (event_table_sections.cpp)
    add_event_sections(*scene.events, sections, indices);
    return indices;
  }
  if (scene.polygons || scene.points2) {
    add_geo_input_sections(scene, indices, add);
    return indices;
  }
  indices.positions = add(format::kSectionPositions, sizeof(format::Float3), scene.positions.size(),
                          as_bytes(scene.positions));
  if (input_kind_of(scene) != InputKind::kTriangles) return indices;
  indices.triangles = add(format::kSectionTriangles, sizeof(format::Triangle),
                          scene.triangles.size(), as_bytes(scene.triangles));
  indices.triangle_mesh = add(format::kSectionTriangleMesh, sizeof(std::uint32_t),
                              scene.triangle_mesh.size(), as_bytes(scene.triangle_mesh));
  if (!scene.normals.empty())
    indices.normals = add(format::kSectionNormals, sizeof(format::Float3), scene.normals.size(),
                          as_bytes(scene.normals));
  return indices;
}

}  // namespace

InputKind input_kind_of(const Scene& scene) {
  if (scene.events) return InputKind::kEvents;
  if (scene.polygons) return InputKind::kPolygons2;
  if (scene.points2) return InputKind::kPoint2;
  return scene.triangles.empty() ? InputKind::kPoint3 : InputKind::kTriangles;
}

namespace {

// A blob holds one input: a 2D one (GeoJSON, CSV) alone, never several nor beside meshes.
Scene import_geo_scene(const std::vector<std::string>& inputs, const BuildProgress& progress,
                       const ImportLimits& limits, const GeoImportOptions& geo) {
  for (const std::string& input : inputs)
    if (is_geo_input_name(input) && inputs.size() > 1)
      throw ImportError(input + ": a 2D input (GeoJSON, CSV) must be the blob's only input (" +
                        std::to_string(inputs.size()) + " inputs given: build one blob each)");
  if (progress) progress("import", 0, 1);
  GeoInput in = import_geo_file(inputs.front(), geo, limits);
  if (progress) progress("import", 1, 1);
  Scene scene;
  scene.sources.push_back(std::move(in.source));
  scene.accessed.read.push_back(inputs.front());
  normalize_accesses(scene.accessed);
  scene.polygons = std::move(in.polygons);
  scene.points2 = std::move(in.points);
  return scene;
}

}  // namespace

Scene import_scene(const std::vector<std::string>& inputs, unsigned threads,
                   const BuildProgress& progress, const ImportLimits& limits,
                   const GeoImportOptions& geo, const EventColumns& events) {
  if (events.active()) return import_event_scene(inputs, events, limits);  // issue 18
  for (const std::string& input : inputs)
    if (is_geo_input_name(input)) return import_geo_scene(inputs, progress, limits, geo);
  std::vector<ImportedFile> files(inputs.size());
  if (progress) progress("import", 0, inputs.size());
  parallel_for(inputs.size(), threads,
               [&](std::size_t i) { files[i] = import_file(inputs[i], limits); });
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

CompiledBlob compile_blob_pieces(const Scene& scene, const BuildOptions& given,
                                 std::vector<AccelReport>* reports) {
  // `--accel auto` becomes the structure advise recommends on this scene (advise.hpp).
  BuildOptions options = given;
  const std::vector<AutoChoice> advice =
      resolve_auto_requests(scene, options.structures, options.threads);
  check_requests(scene, options);
  CompiledBlob blob;
  std::vector<SectionPayload> sections;
  sections.push_back({});  // the manifest, filled in once the other indices are known
  const InputSectionIndices input = add_input_sections(scene, sections);
  // Each structure is built in turn (each build is parallel inside) and kept in the result,
  // since sections only borrow their bytes.
  std::vector<std::vector<std::uint32_t>> owned_sections;
  for (const StructureRequest& request : options.structures) {
    const auto start = std::chrono::steady_clock::now();
    blob.structures.push_back(
        find_structure_builder(request.kind)->build(scene, request, options.threads));
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const BuiltStructure& built = blob.structures.back();
    std::string summary = built.summary;
    for (const AutoChoice& choice : advice)
      if (&options.structures[choice.structure] == &request)
        summary =
            "chosen by --accel auto (" + choice.advice.recommendation.reason + "); " + summary;
    if (reports) reports->push_back({request.name, request.kind, summary, seconds});
    auto& owned = owned_sections.emplace_back();
    for (const SectionPayload& section : built.sections) {
      sections.push_back(section);
      owned.push_back(std::uint32_t(sections.size() - 1));
    }
  }
  blob.manifest = build_manifest(scene, options, input, blob.structures, owned_sections, advice);
  sections[0] = {format::kSectionManifest,
                 std::uint16_t(format::SectionFlag::kRequired),
                 1,
                 blob.manifest.size(),
                 blob.manifest,
                 false};
  blob.pieces = lay_out_blob(sections, options.compression, options.threads);
  return blob;
}

std::vector<std::byte> compile_blob(const Scene& scene, const BuildOptions& options,
                                    std::vector<AccelReport>* reports) {
  return compile_blob_pieces(scene, options, reports).pieces.concatenate();
}

}  // namespace kiln
