// A small debug renderer for `kiln render`, on the runtime library alone: a pinhole camera,
// one primary ray per pixel through any ray structure of a blob (its RayQueries, found through
// the runtime's registry) into a buffer of samples, the samples coloured (shading, normals, depth
// or a traversal cost heatmap with its legend), captions, and PNG output written atomically.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "kiln/formats/geometry.hpp"
#include "kiln/runtime/ray.hpp"
#include "kiln/runtime/triangle_geometry.hpp"

namespace kiln {
class Blob;
class RayQueries;
}  // namespace kiln

namespace kiln::render {

// Larger sides are refused: they are typos, and the buffers would not fit in memory.
inline constexpr std::uint32_t kMaxImageSide = 16384;
// Most pixels of one image (all panels together): 2^26 samples are about 1.6 GB.
inline constexpr std::uint64_t kMaxImagePixels = std::uint64_t{1} << 26;

struct Camera {
  format::Float3 eye{0, 0, 1};
  format::Float3 target{0, 0, 0};
  float fov_degrees = 45;  // vertical field of view
};

// "eye_x,eye_y,eye_z,target_x,target_y,target_z,fov_degrees": seven finite numbers, eye apart
// from target, 0 < fov < 180. nullopt with the reason in `error` otherwise.
std::optional<Camera> parse_camera(std::string_view text, std::string& error);
// "WxH", both in 1..kMaxImageSide. nullopt with the reason in `error` otherwise.
struct Size {
  std::uint32_t width = 0, height = 0;
};
std::optional<Size> parse_size(std::string_view text, std::string& error);

// A camera looking at the centre of the box [lo, hi] from a fixed direction (front, right and
// above, +y up), far enough back for the box's eight corners to fit the frame (5 % margin).
Camera frame_bounds(const format::Float3& lo, const format::Float3& hi, Size size);
// frame_bounds on the bounds of the blob's input (over every kept vertex or 3D point).
Camera default_camera(const Blob& blob, Size size);

// Primary rays through pixel centres (y = 0 is the top row). The camera's basis is worked out
// once, on construction, not per pixel. Camera maths runs in double and rounds once to float.
class PixelRays {
 public:
  // The view's unit axes in world space (+y is up unless the view is vertical), the tangent of
  // half the vertical field of view and the image's width / height.
  struct Basis {
    format::Double3 forward, right, up;
    double tan_half = 1, aspect = 1;
  };

  PixelRays(const Camera& camera, Size size);
  Ray operator()(std::uint32_t x, std::uint32_t y) const;
  const Basis& basis() const { return basis_; }

 private:
  format::Float3 eye_;
  Size size_;
  Basis basis_;
};

// What one primary ray found.
struct Sample {
  float t = 0;                     // hit distance (valid when hit)
  format::Float3 normal{0, 0, 0};  // geometric normal of the hit, unit length, facing the ray
  std::uint32_t nodes = 0;         // node visits
  std::uint32_t tests = 0;         // primitive tests: triangles, or voxels / leaf slots
  bool hit = false;
  std::uint32_t cost() const { return nodes + tests; }
};

struct Samples {
  Size size;
  std::vector<Sample> pixels;  // row-major, top row first
};

// The names of the structures of a blob that trace rays, in blob order.
std::vector<std::string> ray_structures(const Blob& blob);
// The first of them (what `kiln render` uses without --accel); throws BlobError when none.
std::string default_structure(const Blob& blob);

// One closest-hit query per pixel, counting its work; rows are split across up to `threads`
// threads (0 = all cores) and the result does not depend on the count.
Samples trace_view(const RayQueries& rays, const Camera& camera, Size size, unsigned threads);
// trace_view on the structure named `accel` (empty: the first that traces rays). Throws
// BlobError when the blob has no such ray structure.
Samples trace_view(const Blob& blob, const std::string& accel, const Camera& camera, Size size,
                   unsigned threads);

struct CostSummary {
  double mean_cost = 0, mean_nodes = 0, mean_tests = 0;  // per primary ray, misses included
  double hit_fraction = 0;
  std::uint32_t max_cost = 0;
};
CostSummary summarize(const Samples& samples);

enum class Mode { kShade, kNormal, kDepth, kHeatmap };
// "shade", "normal", "depth", "heatmap".
std::optional<Mode> parse_mode(std::string_view name);

struct Rgb {
  std::uint8_t r = 0, g = 0, b = 0;
};

// An RGB8 image, row-major, top row first.
struct Image {
  std::uint32_t width = 0, height = 0;
  std::vector<Rgb> pixels;
  Image() = default;
  Image(std::uint32_t w, std::uint32_t h, Rgb fill = {})
      : width(w), height(h), pixels(std::size_t(w) * h, fill) {}
  Rgb& at(std::uint32_t x, std::uint32_t y) { return pixels[std::size_t(y) * width + x]; }
  const Rgb& at(std::uint32_t x, std::uint32_t y) const {
    return pixels[std::size_t(y) * width + x];
  }
};

// The heatmap's top: the 99th percentile of the cost over every sample of every panel (at least
// 1), so a few extreme rays do not wash the rest out; costs above it get the top colour.
std::uint32_t heatmap_scale(std::span<const Samples* const> panels);

// Depth range shared by panels: nearest and farthest hit (0, 1 when nothing is hit).
struct DepthRange {
  float near = 0, far = 1;
};
DepthRange depth_range(std::span<const Samples* const> panels);

// The viridis colour map at v in [0, 1] (clamped).
Rgb viridis(float v);
// Distinct heatmap colours at most: with the few colours of captions and legend an image stays
// within a 256-entry PNG palette (a third of the bytes of RGB on a noisy heatmap).
inline constexpr std::uint32_t kHeatLevels = 200;
// The heatmap colour of `cost` on the scale 0..scale (above: the top colour): viridis at
// min(cost, scale) / scale, rounded to one of at most kHeatLevels steps (every integer cost
// gets its own step while scale < kHeatLevels).
Rgb heat_colour(std::uint32_t cost, std::uint32_t scale);

// Colours samples: shade (two lights on a grey surface), normal (n * 0.5 + 0.5 as RGB), depth
// (near bright, far dark, on `depth`), heatmap (cost / heat_scale on viridis). Misses get a
// constant background, except in the heatmap, which shows every ray's cost.
Image colour(const Samples& samples, Mode mode, std::uint32_t heat_scale, DepthRange depth,
             const Camera& camera);

// A caption in the top-left corner of the image region starting at column x0.
void draw_caption(Image& image, int x0, std::string_view text);
// The heatmap legend: `title` over a bar of the heatmap's colours with "0", the middle and the
// top of the scale under it, centred at the bottom of the image (top label "N+" when some costs
// were clamped to it). Left out on images under 64x48.
void draw_legend(Image& image, std::uint32_t heat_scale, bool clamped, std::string_view title);

// Places images side by side, left to right (all the same height).
Image side_by_side(std::span<const Image> panels);

// The PNG file bytes of an image: 8-bit palette when it has at most 256 colours (heatmaps),
// else RGB; compressed by stb_image_write's deflate. The same pixels give the same bytes.
std::vector<std::byte> encode_png(const Image& image);

}  // namespace kiln::render
