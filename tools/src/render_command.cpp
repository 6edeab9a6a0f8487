// `kiln render`: checks the options, traces one panel per structure, colours and captions them,
// writes the PNG atomically and reports the mean traversal cost per ray.
#include <charconv>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "commands.hpp"
#include "kiln/runtime/atomic_file.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "kiln/tools/render.hpp"
#include "kiln/tools/render_map.hpp"
#include "render_events.hpp"

namespace kiln::cli {

namespace {

// Options are kept as text and checked by run_render, so every bad value gets one line on
// stderr, exit status 1 and no output file.
struct RenderArgs {
  std::string blob, out, accel;
  std::string mode;  // empty: heatmap with --compare, else shade
  std::string size = "640x400";
  std::string camera;   // empty: frame the bounds of the blob's input
  std::string compare;  // comma-separated structure names
  unsigned threads = 0;
  bool json = false;
  EventRenderArgs events;  // issue 18: render_events.cpp
};

// The checked options.
struct Settings {
  std::string mode_name;
  render::Mode mode;
  render::Size size;
  std::optional<render::Camera> camera;  // nullopt: the default camera
};

struct Panel {
  std::string name;
  bool voxels = false;  // its primitive tests are voxel tests
  render::Samples samples;
  render::CostSummary summary;
};

std::vector<std::string> split_names(const std::string& list) {
  std::vector<std::string> names;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = list.find(',', start);
    names.push_back(list.substr(start, comma - start));
    if (comma == std::string::npos) return names;
    start = comma + 1;
  }
}

std::string fixed(double v, int digits) {
  char text[64];
  std::snprintf(text, sizeof(text), "%.*f", digits, v);
  return text;
}

// "a, b, c", or "none".
std::string joined(const std::vector<std::string>& names) {
  std::string list;
  for (const auto& name : names) {
    if (!list.empty()) list += ", ";
    list += name;
  }
  return list.empty() ? "none" : list;
}

// In --camera syntax, each float in its shortest form that reads back the same.
std::string camera_text(const render::Camera& c) {
  std::string text;
  for (const float v :
       {c.eye.x, c.eye.y, c.eye.z, c.target.x, c.target.y, c.target.z, c.fov_degrees}) {
    char number[32];
    const auto end = std::to_chars(number, number + sizeof number, v).ptr;
    if (!text.empty()) text += ',';
    text.append(number, end);
  }
  return text;
}

// Everything checkable before touching the blob; nullopt with the reason in `error` otherwise.
std::optional<Settings> check_options(const RenderArgs& args, std::string& error) {
  if (!args.compare.empty() && !args.accel.empty()) {
    error = "--compare and --accel exclude each other (--compare lists the structures)";
    return std::nullopt;
  }
  if (!args.compare.empty())
    for (const auto& name : split_names(args.compare))
      if (name.empty()) {
        error = "--compare '" + args.compare + "' has an empty name";
        return std::nullopt;
      }
  Settings s;
  s.mode_name = !args.mode.empty() ? args.mode : args.compare.empty() ? "shade" : "heatmap";
  const auto mode = render::parse_mode(s.mode_name);
  if (!mode) {
    error = "--mode '" + s.mode_name + "' must be shade, normal, depth or heatmap";
    return std::nullopt;
  }
  s.mode = *mode;
  const auto size = render::parse_size(args.size, error);
  if (!size) return std::nullopt;
  s.size = *size;
  if (!args.camera.empty() && !(s.camera = render::parse_camera(args.camera, error)))
    return std::nullopt;
  return s;
}

// One panel per structure named, each traced with its RayQueries. Throws BlobError naming the
// blob's ray structures when a name is not one of them.
std::vector<Panel> trace_panels(const Blob& blob, const std::vector<std::string>& names,
                                const Settings& s, unsigned threads) {
  std::vector<Panel> panels;
  for (const auto& name : names) {
    const auto view = blob.structure(name) ? open_structure(blob, name) : nullptr;
    if (view == nullptr || view->rays() == nullptr)
      throw BlobError(blob.name() + ": has no ray structure '" + name +
                      "' (it has: " + joined(render::ray_structures(blob)) + ")");
    const RayQueries& rays = *view->rays();
    Panel p{name,
            rays.record_size() == sizeof(VoxelHitRecord),
            render::trace_view(rays, *s.camera, s.size, threads),
            {}};
    p.summary = render::summarize(p.samples);
    panels.push_back(std::move(p));
  }
  return panels;
}

// What the heatmap counts as primitive tests, for its legend and the report.
const char* tests_name(bool voxels) {
  return voxels ? "voxel tests" : "triangle tests";
}

// The panels coloured on one heat scale and depth range (so they compare), captioned, side
// by side, with the heatmap's legend.
render::Image compose(const std::vector<Panel>& panels, const Settings& s,
                      std::uint32_t heat_scale) {
  std::vector<const render::Samples*> all;
  for (const auto& p : panels) all.push_back(&p.samples);
  const render::DepthRange depth = render::depth_range(all);
  bool clamped = false, voxels = false, triangles = false;
  std::vector<render::Image> images;
  for (const auto& p : panels) {
    clamped = clamped || p.summary.max_cost > heat_scale;
    (p.voxels ? voxels : triangles) = true;
    images.push_back(render::colour(p.samples, s.mode, heat_scale, depth, *s.camera));
    if (s.mode == render::Mode::kHeatmap || panels.size() > 1)
      render::draw_caption(images.back(), 0,
                           p.name + "  mean cost " + fixed(p.summary.mean_cost, 1) + " / ray");
  }
  render::Image image = render::side_by_side(images);
  if (s.mode == render::Mode::kHeatmap)
    render::draw_legend(image, heat_scale, clamped,
                        std::string("cost per ray: node visits + ") +
                            (voxels && triangles ? "primitive tests" : tests_name(voxels)));
  return image;
}

void print_json(const RenderArgs& args, const Settings& s, const render::Image& image,
                const std::vector<Panel>& panels, std::uint32_t heat_scale) {
  nlohmann::ordered_json json = {{"image", args.out},
                                 {"width", image.width},
                                 {"height", image.height},
                                 {"mode", s.mode_name},
                                 {"camera", camera_text(*s.camera)}};
  if (s.mode == render::Mode::kHeatmap) json["heat_scale"] = heat_scale;
  json["structures"] = nlohmann::ordered_json::array();
  for (const auto& p : panels)
    json["structures"].push_back({{"name", p.name},
                                  {"mean_cost", p.summary.mean_cost},
                                  {"mean_nodes", p.summary.mean_nodes},
                                  {"mean_tests", p.summary.mean_tests},
                                  {"max_cost", p.summary.max_cost},
                                  {"hit_fraction", p.summary.hit_fraction}});
  std::cout << json.dump() << "\n";
}

void print_text(const RenderArgs& args, const Settings& s, const render::Image& image,
                const std::vector<Panel>& panels, std::uint32_t heat_scale) {
  std::cout << "kiln render: " << args.out << " " << image.width << "x" << image.height << ", "
            << s.mode_name << ", --camera " << camera_text(*s.camera) << "\n";
  if (s.mode == render::Mode::kHeatmap)
    std::cout << "heatmap scale: 0.." << heat_scale
              << " (99th percentile of all panels' per-ray costs)\n";
  for (const auto& p : panels)
    std::cout << p.name << ": mean cost per ray " << fixed(p.summary.mean_cost, 2) << " ("
              << fixed(p.summary.mean_nodes, 2) << " node visits + "
              << fixed(p.summary.mean_tests, 2) << " " << tests_name(p.voxels) << "), max "
              << p.summary.max_cost << ", " << fixed(100.0 * p.summary.hit_fraction, 1)
              << "% of rays hit\n";
}

int fail(const std::string& message) {
  std::cerr << "kiln render: " << message << "\n";
  return 1;
}

int run_render(const RenderArgs& args) {
  try {
    // Opened once: an event table draws a heatmap (render_events.cpp), a 2D layer a map; a blob
    // that does not open gets the 3D path's messages.
    std::string ignored;
    std::optional<Blob> opened = Blob::try_open_file(args.blob, ignored);
    if (opened && opened->input().kind == InputKind::kEvents)
      return run_event_render(*opened, args.accel, args.out, args.size, args.events);
    if (opened && render::is_map_blob(*opened))
      return render::render_map_command(*opened, args.out, args.accel, args.mode, args.size,
                                        args.threads, args.json);
    std::string error;
    std::optional<Settings> s = check_options(args, error);
    if (!s) return fail(error);
    std::error_code ec;
    if (std::filesystem::exists(args.out, ec) &&
        std::filesystem::equivalent(args.blob, args.out, ec))
      return fail("output " + args.out + " is the blob itself");
    const Blob blob = opened ? std::move(*opened) : Blob::open_file(args.blob);
    const std::vector<std::string> names =
        !args.compare.empty() ? split_names(args.compare)
        : args.accel.empty()  ? std::vector<std::string>{render::default_structure(blob)}
                              : std::vector<std::string>{args.accel};
    if (std::uint64_t(s->size.width) * s->size.height * names.size() > render::kMaxImagePixels)
      return fail("--size " + args.size + " x " + std::to_string(names.size()) +
                  " panels is more than " + std::to_string(render::kMaxImagePixels) + " pixels");
    if (!s->camera) s->camera = render::default_camera(blob, s->size);
    const std::vector<Panel> panels = trace_panels(blob, names, *s, args.threads);
    std::vector<const render::Samples*> all;
    for (const auto& p : panels) all.push_back(&p.samples);
    const std::uint32_t heat_scale = render::heatmap_scale(all);
    const render::Image image = compose(panels, *s, heat_scale);
    write_file_atomically(args.out, render::encode_png(image));
    (args.json ? print_json : print_text)(args, *s, image, panels, heat_scale);
    return 0;
  } catch (const std::bad_alloc&) {
    return fail("out of memory");
  } catch (const std::exception& e) {
    return fail(e.what());
  }
}

}  // namespace

Command add_render_command(CLI::App& app) {
  auto args = std::make_shared<RenderArgs>();
  auto* command = app.add_subcommand(
      "render", "Render a view of a blob with one of its ray structures (runtime only) to a PNG");
  command->add_option("blob", args->blob, "The .kiln file")->required();
  command->add_option("-o,--output", args->out, "The PNG to write (atomically)")->required();
  command->add_option("--accel", args->accel,
                      "Ray structure to use, by name (default: the first that traces rays)");
  command->add_option("--mode", args->mode,
                      "shade (default), normal, depth or heatmap (node visits + primitive "
                      "tests per ray on viridis, with a legend; --compare's default). A 2D blob "
                      "(polygon layer, point table) draws a map instead, in an equirectangular "
                      "(plate carree) projection fitted to its bounds: map (default), cells (the "
                      "index's leaf cells over it) or heatmap (cost of a point query per pixel)");
  command->add_option("--size", args->size, "Image size WIDTHxHEIGHT, each 1..16384 (per panel)")
      ->capture_default_str();
  command->add_option("--camera", args->camera,
                      "eye_x,eye_y,eye_z,target_x,target_y,target_z,fov_degrees: seven numbers "
                      "separated by commas, no spaces; fov is vertical, 0..180 exclusive, +y "
                      "is up (default: frame the input's bounds from the front right, above)");
  command->add_option("--compare", args->compare,
                      "Structures to render side by side, by name, separated by commas: one "
                      "shared heatmap scale, mean cost per ray in each caption and on stdout");
  add_threads_option(command, args->threads,
                     "Worker threads (0 = all cores); never changes the image");
  command->add_flag("--json", args->json, "Mean costs per structure as JSON on stdout");
  add_event_render_options(command, args->events);
  return {command, [args] { return run_render(*args); }};
}

}  // namespace kiln::cli
