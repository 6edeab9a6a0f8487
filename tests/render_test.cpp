// `kiln render` and its library: deterministic PNG bytes, an exact silhouette, traversal costs
// (SBVH below the binned BVH where it should be), the counting voxel casts, and the command line
// (sizes, modes, every structure kind, --compare, bad options).
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "kiln/compiler/build.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/esvo.hpp"
#include "kiln/runtime/voxel_dag.hpp"
#include "kiln/tools/render.hpp"
#include "ray_fixtures.hpp"
#include "test_support.hpp"

#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_STATIC
#define STBI_ONLY_PNG
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wsign-compare"
#include <stb/stb_image.h>
#pragma GCC diagnostic pop

namespace kiln {
namespace {

namespace fs = std::filesystem;
using format::Float3;
using test::quoted;

// The box [lo, hi] as 12 triangles.
Scene box_scene(Float3 lo, Float3 hi) {
  std::vector<Float3> p;
  for (int i = 0; i < 8; ++i)
    p.push_back({i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z});
  const std::vector<format::Triangle> t = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6},
                                           {0, 1, 4}, {1, 5, 4}, {2, 6, 3}, {3, 6, 7},
                                           {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  return test::make_scene(std::move(p), t);
}

// A blob of `scene` with the structures named (voxel ones on a `resolution` grid).
std::vector<std::byte> compile(const Scene& scene, const std::vector<std::string>& kinds,
                               std::uint32_t resolution = 64) {
  BuildOptions options;
  options.inputs = {"generated"};
  options.threads = 2;
  const std::map<std::string, std::string> flags = {{"--resolution", std::to_string(resolution)}};
  for (const auto& kind : kinds)
    options.structures.push_back(resolve_structure_request(kind, flags));
  return compile_blob(scene, options);
}

// Everything that makes one picture, for comparing bytes.
std::vector<std::byte> render_png(const Blob& blob, const std::string& accel, render::Mode mode,
                                  render::Size size, unsigned threads) {
  const render::Camera camera = render::default_camera(blob, size);
  const render::Samples samples = render::trace_view(blob, accel, camera, size, threads);
  const render::Samples* all[] = {&samples};
  const std::uint32_t scale = render::heatmap_scale(all);
  render::Image image = render::colour(samples, mode, scale, render::depth_range(all), camera);
  render::draw_caption(
      image, 0, accel + "  mean cost " + std::to_string(render::summarize(samples).mean_cost));
  if (mode == render::Mode::kHeatmap) render::draw_legend(image, scale, true, "cost per ray");
  return render::encode_png(image);
}

struct Decoded {
  int width = 0, height = 0;
  std::vector<render::Rgb> pixels;
};

// The PNG decoded by stb_image (an independent decoder: it checks the encoder's output).
Decoded decode(std::span<const std::byte> png) {
  Decoded d;
  int channels = 0;
  unsigned char* data = stbi_load_from_memory(reinterpret_cast<const unsigned char*>(png.data()),
                                              int(png.size()), &d.width, &d.height, &channels, 3);
  if (data == nullptr) return {};
  d.pixels.resize(std::size_t(d.width) * d.height);
  std::memcpy(d.pixels.data(), data, d.pixels.size() * 3);
  stbi_image_free(data);
  return d;
}

bool same(render::Rgb a, render::Rgb b) {
  return a.r == b.r && a.g == b.g && a.b == b.b;
}

// An icosphere as OBJ text, for the command line tests (no corpus needed).
std::string sphere_obj() {
  const Scene s = test::icosphere(3);
  std::ostringstream out;
  out.precision(9);
  for (const auto& p : s.positions) out << "v " << p.x << " " << p.y << " " << p.z << "\n";
  for (const auto& t : s.triangles)
    out << "f " << t.v[0] + 1 << " " << t.v[1] + 1 << " " << t.v[2] + 1 << "\n";
  return out.str();
}

std::string write_sphere(const test::TempDir& dir) {
  const std::string path = dir.file("sphere.obj");
  std::ofstream(path) << sphere_obj();
  return path;
}

std::size_t lines(const std::string& text) {
  return std::size_t(std::count(text.begin(), text.end(), '\n'));
}

TEST(Render, PngBytesAreIdenticalAcrossRunsAndThreadCounts) {
  Scene scene = test::icosphere(3);
  const auto bytes = compile(scene, {"bvh", "sbvh", "kdtree", "dag", "esvo"});
  const AlignedBuffer aligned = test::aligned_copy(bytes);
  const Blob blob = Blob::open_memory(aligned.bytes());
  const render::Size size{97, 61};  // odd sizes: rows do not split evenly across threads
  for (const char* accel : {"bvh", "sbvh", "kdtree", "dag", "esvo"})
    for (const auto mode : {render::Mode::kShade, render::Mode::kNormal, render::Mode::kDepth,
                            render::Mode::kHeatmap}) {
      const auto first = render_png(blob, accel, mode, size, 1);
      EXPECT_EQ(first, render_png(blob, accel, mode, size, 1)) << accel;
      EXPECT_EQ(first, render_png(blob, accel, mode, size, 2)) << accel;
      EXPECT_EQ(first, render_png(blob, accel, mode, size, 5)) << accel;
      const Decoded d = decode(first);
      EXPECT_EQ(d.width, 97) << accel;
      EXPECT_EQ(d.height, 61) << accel;
    }
}

// A cube seen head-on: eye (0, 0, 5), target the origin, 90 degrees vertical, 96x64 pixels.
// The visible face z = 1 lies 4 units away, so its edges x, y = +-1 project to +-1/4 in units of
// tan(45) = 1. Pixel centres are at u = (2 (x + 0.5) / 96 - 1) * 1.5 (aspect 3/2) and
// v = 1 - 2 (y + 0.5) / 64: |u| < 1/4 gives columns 40..55, |v| < 1/4 rows 24..39.
// Every structure must hit exactly that rectangle, up to one pixel at its border (the voxel
// structures' surfaces sit up to a few voxels of 2/64 off the faces: under a pixel here).
TEST(Render, BoxSilhouetteIsTheProjectedRectangle) {
  const Scene scene = box_scene({-1, -1, -1}, {1, 1, 1});
  const auto bytes = compile(scene, {"bvh", "sbvh", "kdtree", "dag", "esvo"});
  const AlignedBuffer aligned = test::aligned_copy(bytes);
  const Blob blob = Blob::open_memory(aligned.bytes());
  std::string error;
  const auto camera = render::parse_camera("0,0,5,0,0,0,90", error);
  ASSERT_TRUE(camera) << error;
  const render::Size size{96, 64};
  const int x0 = 40, x1 = 55, y0 = 24, y1 = 39;
  for (const std::string accel : {"bvh", "sbvh", "kdtree", "dag", "esvo"}) {
    const bool triangles = accel != "dag" && accel != "esvo";
    const auto samples = render::trace_view(blob, accel, *camera, size, 2);
    const render::Samples* all[] = {&samples};
    const render::Image image =
        render::colour(samples, render::Mode::kShade, 1, render::depth_range(all), *camera);
    const render::Rgb background = image.at(0, 0);
    int checked = 0, hits = 0;
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 96; ++x) {
        // Pixels next to the rectangle's outline are not checked.
        const bool near_x = x == x0 - 1 || x == x0 || x == x1 || x == x1 + 1;
        const bool near_y = y == y0 - 1 || y == y0 || y == y1 || y == y1 + 1;
        const bool border =
            (near_x && y >= y0 - 1 && y <= y1 + 1) || (near_y && x >= x0 - 1 && x <= x1 + 1);
        const bool inside = x >= x0 && x <= x1 && y >= y0 && y <= y1;
        const auto& s = samples.pixels[std::size_t(y) * 96 + std::size_t(x)];
        hits += s.hit;
        if (border) continue;
        ++checked;
        EXPECT_EQ(s.hit, inside) << accel << " pixel " << x << "," << y;
        EXPECT_EQ(same(image.at(std::uint32_t(x), std::uint32_t(y)), background), !inside)
            << accel << " pixel " << x << "," << y;
        if (inside && s.hit) {
          // The face seen is z = 1, t = 4 / |dir.z| away. Triangles give its normal; a voxel
          // gives the face the ray entered, which is ambiguous where pixel rays meet voxel
          // edges exactly (the box's faces lie on the grid), so only its side is checked.
          const float t =
              4.0f /
              std::fabs(render::PixelRays(*camera, size)(std::uint32_t(x), std::uint32_t(y)).dir.z);
          if (triangles) {
            EXPECT_NEAR(s.normal.z, 1.0f, 1e-3f) << accel << " pixel " << x << "," << y;
            EXPECT_NEAR(s.t, t, 1e-4f * t) << accel << " pixel " << x << "," << y;
          } else {
            EXPECT_GE(s.normal.z, 0.0f) << accel << " pixel " << x << "," << y;
            EXPECT_NEAR(s.t, t, 0.1f) << accel << " pixel " << x << "," << y;
          }
        }
      }
    EXPECT_GT(checked, 96 * 64 - 200);
    // The exact triangle structures hit the 16 x 16 rectangle exactly.
    if (triangles) {
      EXPECT_EQ(hits, 256) << accel;
    }
  }
}

// The Khronos 2CylinderEngine (a CAD model: long thin triangles crossing each other) is where
// spatial splits pay: the same view costs fewer node visits + triangle tests per ray on the SBVH.
TEST(Render, SbvhCostsLessPerRayThanBinnedBvhOnTheEngine) {
  KILN_REQUIRE_CORPUS();
  const Scene scene =
      import_scene({test::mesh_path("gltf/2CylinderEngine-glTF-Draco/2CylinderEngine.gltf")}, 2);
  const auto bytes = compile(scene, {"bvh", "sbvh"});
  const AlignedBuffer aligned = test::aligned_copy(bytes);
  const Blob blob = Blob::open_memory(aligned.bytes());
  const render::Size size{160, 120};
  const render::Camera camera = render::default_camera(blob, size);
  const auto bvh = render::summarize(render::trace_view(blob, "bvh", camera, size, 2));
  const auto sbvh = render::summarize(render::trace_view(blob, "sbvh", camera, size, 2));
  std::printf("2CylinderEngine 160x120 default view: mean cost per ray bvh %.2f, sbvh %.2f\n",
              bvh.mean_cost, sbvh.mean_cost);
  EXPECT_GT(bvh.hit_fraction, 0.1);  // the view shows the model
  EXPECT_EQ(bvh.hit_fraction, sbvh.hit_fraction);
  EXPECT_LT(sbvh.mean_cost, bvh.mean_cost);
}

// The counting casts find exactly what the plain casts find, and count some work for a hit.
TEST(Render, VoxelCountingCastsAgreeWithPlainCasts) {
  const Scene scene = test::icosphere(3);
  const auto bytes = compile(scene, {"dag", "esvo"});
  const AlignedBuffer aligned = test::aligned_copy(bytes);
  const Blob blob = Blob::open_memory(aligned.bytes());
  const VoxelDagView dag = VoxelDagView::from_blob(blob, "dag");
  const EsvoView esvo = EsvoView::from_blob(blob, "esvo");
  const render::Size size{40, 30};
  const render::PixelRays rays(render::default_camera(blob, size), size);
  int hits = 0;
  for (std::uint32_t y = 0; y < size.height; ++y)
    for (std::uint32_t x = 0; x < size.width; ++x) {
      const Ray ray = rays(x, y);
      Cost dc;
      const VoxelHit a = dag.intersect(ray), b = dag.intersect_counting(ray, dc);
      EXPECT_EQ(std::memcmp(&a, &b, sizeof a), 0);
      Cost ec;
      const VoxelHit c = esvo.intersect(ray), d = esvo.intersect_counting(ray, ec);
      EXPECT_EQ(std::memcmp(&c, &d, sizeof c), 0);  // the level and colour included
      if (a.hit()) {
        ++hits;
        EXPECT_GE(dc.nodes, dag.levels() - 1);  // one cell per level down to a leaf at least
        EXPECT_GE(dc.tests, 1u);
      }
      if (c.hit()) {
        EXPECT_GE(ec.nodes, 1u);
        EXPECT_GE(ec.tests, 1u);
      }
    }
  EXPECT_GT(hits, 100);
}

TEST(Render, ParsesCameraAndSize) {
  std::string error;
  const auto camera = render::parse_camera("1,2.5,-3,0,0,0,60", error);
  ASSERT_TRUE(camera) << error;
  EXPECT_EQ(camera->eye.y, 2.5f);
  EXPECT_EQ(camera->eye.z, -3.0f);
  EXPECT_EQ(camera->fov_degrees, 60.0f);
  for (const char* bad :
       {"", "1,2,3", "1,2,3,4,5,6,7,8", "1,2,3,1,2,3,45", "0,0,1,0,0,0,0", "0,0,1,0,0,0,180",
        "0,0,1,0,0,0,nan", "0,0,1,0,0,0,inf", "0,0,1,0,0,0,1e400", "0,0,1,0,0,x,45",
        "0,0,1,,0,0,45", " 0,0,1,0,0,0,45"}) {
    error.clear();
    EXPECT_FALSE(render::parse_camera(bad, error)) << bad;
    EXPECT_FALSE(error.empty()) << bad;
  }
  const auto size = render::parse_size("640x400", error);
  ASSERT_TRUE(size);
  EXPECT_EQ(size->width, 640u);
  EXPECT_EQ(size->height, 400u);
  for (const char* bad : {"", "0x10", "10x0", "16385x10", "10x99999999999999999999", "640", "x",
                          "-1x5", "6.5x5", "5x5x5"})
    EXPECT_FALSE(render::parse_size(bad, error)) << bad;
  EXPECT_TRUE(render::parse_size("16384x1", error));
}

TEST(Render, ViridisEndsAndLegendColours) {
  // The map's published 8-bit ends: #440154 and #FDE725.
  EXPECT_TRUE(same(render::viridis(0), {0x44, 0x01, 0x54}));
  EXPECT_TRUE(same(render::viridis(1), {0xFD, 0xE7, 0x25}));
  EXPECT_TRUE(same(render::viridis(-5), render::viridis(0)));
  EXPECT_TRUE(same(render::viridis(7), render::viridis(1)));
  EXPECT_TRUE(same(render::heat_colour(1000, 50), render::viridis(1)));
  EXPECT_TRUE(same(render::heat_colour(0, 50), render::viridis(0)));
  // Green channel rises monotonically along viridis.
  for (int i = 1; i <= 100; ++i)
    EXPECT_GE(render::viridis(float(i) / 100).g, render::viridis(float(i - 1) / 100).g);
  // The legend shows both ends of the map.
  render::Image image(400, 300, {1, 2, 3});
  render::draw_legend(image, 80, false, "cost");
  bool low = false, high = false;
  for (const auto& p : image.pixels)
    low = low || same(p, render::viridis(0)), high = high || same(p, render::viridis(1));
  EXPECT_TRUE(low);
  EXPECT_TRUE(high);
}

// --- the command line -----------------------------------------------------------------------

TEST(RenderCli, WritesPngsOfTheRequestedSizeForEveryStructureAndMode) {
  test::TempDir dir;
  const std::string blob = dir.file("sphere.kiln");
  const auto build =
      test::run_kiln("build " + quoted(write_sphere(dir)) + " -o " + quoted(blob) +
                     " --accel bvh --accel sbvh --accel kdtree --accel dag --accel esvo "
                     "--resolution 64");
  ASSERT_EQ(build.exit_code, 0) << build.err;
  for (const char* accel : {"bvh", "sbvh", "kdtree", "dag", "esvo"})
    for (const char* mode : {"shade", "normal", "depth", "heatmap"}) {
      const std::string png = dir.file(std::string(accel) + "_" + mode + ".png");
      const auto r = test::run_kiln("render " + quoted(blob) + " -o " + quoted(png) + " --accel " +
                                    accel + " --mode " + mode + " --size 73x41");
      ASSERT_EQ(r.exit_code, 0) << accel << " " << mode << ": " << r.err;
      EXPECT_NE(r.out.find(std::string(accel) + ": mean cost per ray"), std::string::npos) << r.out;
      const Decoded d = decode(test::read_file(png));
      EXPECT_EQ(d.width, 73) << accel << " " << mode;
      EXPECT_EQ(d.height, 41) << accel << " " << mode;
    }
  // Without --accel: the first ray structure, as kiln trace.
  const auto r = test::run_kiln("render " + quoted(blob) + " -o " + quoted(dir.file("d.png")));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out.find("bvh: mean"), r.out.find('\n') + 1) << r.out;
  EXPECT_EQ(decode(test::read_file(dir.file("d.png"))).width, 640);
}

TEST(RenderCli, SameBytesOnOneAndTwoThreads) {
  test::TempDir dir;
  const std::string blob = dir.file("box.kiln");
  test::write_file(blob, compile(box_scene({-1, -2, -1}, {2, 1, 0.5f}), {"bvh", "sbvh"}));
  for (const char* mode : {"shade", "heatmap"}) {
    for (const char* threads : {"1", "2"})
      ASSERT_EQ(test::run_kiln("render " + quoted(blob) + " -o " +
                               quoted(dir.file(std::string("t") + threads + ".png")) +
                               " --compare bvh,sbvh --size 120x90 --mode " + mode + " --threads " +
                               threads)
                    .exit_code,
                0);
    EXPECT_EQ(test::read_file(dir.file("t1.png")), test::read_file(dir.file("t2.png"))) << mode;
  }
}

TEST(RenderCli, CompareReportsEveryStructureOnOneScale) {
  test::TempDir dir;
  const std::string blob = dir.file("sphere.kiln");
  test::write_file(blob, compile(test::icosphere(4), {"bvh", "sbvh", "kdtree"}));
  const std::string png = dir.file("compare.png");
  const auto json = test::run_kiln("render " + quoted(blob) + " -o " + quoted(png) +
                                   " --compare bvh,sbvh,kdtree --size 100x80 --json");
  ASSERT_EQ(json.exit_code, 0) << json.err;
  const auto j = nlohmann::json::parse(json.out);
  EXPECT_EQ(j["mode"], "heatmap");  // --compare's default
  EXPECT_EQ(j["width"], 300);
  ASSERT_EQ(j["structures"].size(), 3u);
  const char* names[] = {"bvh", "sbvh", "kdtree"};
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(j["structures"][i]["name"], names[i]);
    EXPECT_GT(j["structures"][i]["mean_cost"].get<double>(), 1.0);
    EXPECT_NEAR(j["structures"][i]["mean_cost"].get<double>(),
                j["structures"][i]["mean_nodes"].get<double>() +
                    j["structures"][i]["mean_tests"].get<double>(),
                1e-6);
  }
  EXPECT_GE(j["heat_scale"].get<int>(), 1);
  const Decoded d = decode(test::read_file(png));
  EXPECT_EQ(d.width, 300);
  EXPECT_EQ(d.height, 80);

  const auto text = test::run_kiln("render " + quoted(blob) + " -o " + quoted(png) +
                                   " --compare kdtree,bvh --size 100x80");
  ASSERT_EQ(text.exit_code, 0) << text.err;
  EXPECT_NE(text.out.find("kdtree: mean cost per ray"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("bvh: mean cost per ray"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("99th percentile"), std::string::npos) << text.out;
}

TEST(RenderCli, BadOptionsFailWithOneLineAndNoOutput) {
  test::TempDir dir;
  const std::string blob = dir.file("box.kiln");
  test::write_file(blob, compile(box_scene({0, 0, 0}, {1, 1, 1}), {"bvh"}));
  const std::string png = dir.file("out.png");
  const std::string base = "render " + quoted(blob) + " -o " + quoted(png);
  const std::string cases[] = {
      " --size 0x10",
      " --size 10x0",
      " --size 20000x10",
      " --size 64",
      " --camera 1,2,3",
      " --camera 0,0,0,0,0,0,45",
      " --camera 0,0,5,0,0,0,180",
      " --camera 0,0,5,0,0,0,nan",
      " --mode bogus",
      " --accel kdtree",
      " --accel points",
      " --compare bvh,sbvh",
      " --compare bvh,,bvh",
      " --compare bvh --accel bvh",
      " --size 16384x16384 --compare bvh,bvh",
  };
  for (const auto& extra : cases) {
    const auto r = test::run_kiln(base + extra);
    EXPECT_NE(r.exit_code, 0) << extra;
    EXPECT_EQ(r.signal, 0) << extra;
    EXPECT_EQ(lines(r.err), 1u) << extra << ": " << r.err;
    EXPECT_EQ(r.err.rfind("kiln render: ", 0), 0u) << extra << ": " << r.err;
    EXPECT_FALSE(fs::exists(png)) << extra;
  }
  // A missing blob, a blob that is not one, an output folder that does not exist.
  const auto missing =
      test::run_kiln("render " + quoted(dir.file("nope.kiln")) + " -o " + quoted(png));
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_EQ(lines(missing.err), 1u) << missing.err;
  const auto garbage = test::run_kiln("render " + quoted(write_sphere(dir)) + " -o " + quoted(png));
  EXPECT_EQ(garbage.exit_code, 1);
  EXPECT_EQ(lines(garbage.err), 1u) << garbage.err;
  EXPECT_FALSE(fs::exists(png));
  const auto no_dir =
      test::run_kiln("render " + quoted(blob) + " -o " + quoted(dir.file("no/such/dir.png")));
  EXPECT_EQ(no_dir.exit_code, 1);
  EXPECT_EQ(lines(no_dir.err), 1u) << no_dir.err;
  // A blob without ray structures.
  const std::string points = dir.file("points.kiln");
  test::write_file(points, compile(box_scene({0, 0, 0}, {1, 1, 1}), {"points"}));
  const auto none = test::run_kiln("render " + quoted(points) + " -o " + quoted(png));
  EXPECT_EQ(none.exit_code, 1);
  EXPECT_NE(none.err.find("holds no structure that can trace rays"), std::string::npos) << none.err;
  EXPECT_FALSE(fs::exists(png));
  // Nothing but the requested file was left behind (no temporaries).
  for (const auto& entry : fs::directory_iterator(dir.path()))
    EXPECT_EQ(entry.path().filename().string().find(".tmp"), std::string::npos) << entry.path();
}

TEST(RenderCli, HelpGivesTheCameraSyntax) {
  const auto r = test::run_kiln("render --help");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("eye_x,eye_y,eye_z,target_x,target_y,target_z,fov_degrees"),
            std::string::npos)
      << r.out;
}

}  // namespace
}  // namespace kiln
