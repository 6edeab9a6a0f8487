// `kiln render`: checks the options, traces one panel per structure, colours and captions them,
// writes the PNG atomically and reports the mean traversal cost per ray.
#include "kiln/tools/render_command.hpp"

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <vector>

#include "kiln/runtime/atomic_file.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/tools/json_writer.hpp"
#include "kiln/tools/render.hpp"

namespace kiln {

namespace {

struct Panel {
  std::string name;
  render::Samples samples;
  render::CostSummary summary;
  bool voxels = false;
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

// Everything checkable before touching the blob; "" when fine.
std::string check_options(const RenderArgs& args) {
  if (!args.compare.empty() && !args.accel.empty())
    return "--compare and --accel exclude each other (--compare lists the structures)";
  if (!args.compare.empty())
    for (const auto& name : split_names(args.compare))
      if (name.empty()) return "--compare '" + args.compare + "' has an empty name";
  return {};
}

}  // namespace

int run_render(const RenderArgs& args) {
  auto fail = [](const std::string& message) {
    std::cerr << "kiln render: " << message << "\n";
    return 1;
  };
  try {
    std::string error = check_options(args);
    if (!error.empty()) return fail(error);
    const std::string mode_name = !args.mode.empty()     ? args.mode
                                  : args.compare.empty() ? "shade"
                                                         : "heatmap";
    const auto mode = render::parse_mode(mode_name);
    if (!mode) return fail("--mode '" + mode_name + "' must be shade, normal, depth or heatmap");
    const auto size = render::parse_size(args.size, error);
    if (!size) return fail(error);
    std::optional<render::Camera> camera;
    if (!args.camera.empty() && !(camera = render::parse_camera(args.camera, error)))
      return fail(error);
    std::error_code ec;
    if (std::filesystem::exists(args.out, ec) &&
        std::filesystem::equivalent(args.blob, args.out, ec))
      return fail("output " + args.out + " is the blob itself");

    const Blob blob = Blob::open_file(args.blob);
    std::vector<std::string> names =
        args.compare.empty()
            ? std::vector<std::string>{args.accel.empty() ? render::default_structure(blob)
                                                          : args.accel}
            : split_names(args.compare);
    const auto available = render::ray_structures(blob);
    for (const auto& name : names)
      if (std::find(available.begin(), available.end(), name) == available.end())
        return fail(args.blob + ": has no ray structure '" + name +
                    "' (it has: " + joined(available) + ")");
    if (std::uint64_t(size->width) * size->height * names.size() > render::kMaxImagePixels)
      return fail("--size " + args.size + " x " + std::to_string(names.size()) +
                  " panels is more than " + std::to_string(render::kMaxImagePixels) + " pixels");
    if (!camera) camera = render::default_camera(blob, *size);

    std::vector<Panel> panels;
    for (const auto& name : names) {
      Panel p{name, render::trace_view(blob, name, *camera, *size, args.threads), {}, false};
      p.summary = render::summarize(p.samples);
      const auto* structure = blob.acceleration(name);  // trace_view found it
      p.voxels = structure->dag() != nullptr || structure->esvo() != nullptr;
      panels.push_back(std::move(p));
    }
    std::vector<const render::Samples*> all;
    for (const auto& p : panels) all.push_back(&p.samples);
    // One scale and one depth range for every panel, so their colours compare.
    const std::uint32_t heat_scale = render::heatmap_scale(all);
    const render::DepthRange depth = render::depth_range(all);
    bool clamped = false;
    std::vector<render::Image> images;
    for (const auto& p : panels) {
      clamped = clamped || p.summary.max_cost > heat_scale;
      images.push_back(render::colour(p.samples, *mode, heat_scale, depth, *camera));
      if (*mode == render::Mode::kHeatmap || panels.size() > 1)
        render::draw_caption(images.back(), 0,
                             p.name + "  mean cost " + fixed(p.summary.mean_cost, 1) + " / ray");
    }
    render::Image image = render::side_by_side(images);
    if (*mode == render::Mode::kHeatmap) {
      bool voxels = false, triangles = false;
      for (const auto& p : panels) (p.voxels ? voxels : triangles) = true;
      const char* title = voxels && triangles ? "cost per ray: node visits + primitive tests"
                          : voxels            ? "cost per ray: node visits + voxel tests"
                                              : "cost per ray: node visits + triangle tests";
      render::draw_legend(image, heat_scale, clamped, title);
    }
    write_file_atomically(args.out, render::encode_png(image));

    if (args.json) {
      JsonWriter json(std::cout);
      json.begin_object()
          .field("image", args.out)
          .field("width", image.width)
          .field("height", image.height)
          .field("mode", mode_name)
          .field("camera", camera_text(*camera));
      if (*mode == render::Mode::kHeatmap) json.field("heat_scale", heat_scale);
      json.key("structures").begin_array();
      for (const auto& p : panels)
        json.begin_object()
            .field("name", p.name)
            .field("mean_cost", p.summary.mean_cost)
            .field("mean_nodes", p.summary.mean_nodes)
            .field("mean_tests", p.summary.mean_tests)
            .field("max_cost", p.summary.max_cost)
            .field("hit_fraction", p.summary.hit_fraction)
            .end_object();
      json.end_array().end_object();
      std::cout << "\n";
    } else {
      std::cout << "kiln render: " << args.out << " " << image.width << "x" << image.height << ", "
                << mode_name << ", --camera " << camera_text(*camera) << "\n";
      if (*mode == render::Mode::kHeatmap)
        std::cout << "heatmap scale: 0.." << heat_scale
                  << " (99th percentile of all panels' per-ray costs)\n";
      for (const auto& p : panels)
        std::cout << p.name << ": mean cost per ray " << fixed(p.summary.mean_cost, 2) << " ("
                  << fixed(p.summary.mean_nodes, 2) << " node visits + "
                  << fixed(p.summary.mean_tests, 2)
                  << (p.voxels ? " voxel tests" : " triangle tests") << "), max "
                  << p.summary.max_cost << ", " << fixed(100.0 * p.summary.hit_fraction, 1)
                  << "% of rays hit\n";
    }
    return 0;
  } catch (const std::bad_alloc&) {
    return fail("out of memory");
  } catch (const std::exception& e) {
    return fail(e.what());
  }
}

}  // namespace kiln
