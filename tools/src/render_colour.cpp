// Turning samples into colours: shading, normals, depth and the cost heatmap on viridis.
#include <algorithm>
#include <cmath>
#include <limits>

#include "kiln/tools/render.hpp"

namespace kiln::render {

namespace {

// Viridis (van der Walt & Smith, 2015), perceptually uniform and readable in grey and by
// colour-blind viewers: every 16th entry (and the last) of the 256-entry table `_viridis_data`
// in matplotlib's lib/matplotlib/_cm_listed.py, i.e. entries 0, 16, ..., 240, 255. Between
// them it is interpolated linearly, which stays within about 1/255 of the full table.
constexpr float kViridis[17][3] = {
    {0.267004f, 0.004874f, 0.329415f}, {0.282327f, 0.094955f, 0.417331f},
    {0.278826f, 0.175490f, 0.483397f}, {0.258965f, 0.251537f, 0.524736f},
    {0.229739f, 0.322361f, 0.545706f}, {0.199430f, 0.387607f, 0.554642f},
    {0.172719f, 0.448791f, 0.557885f}, {0.149039f, 0.508051f, 0.557250f},
    {0.127568f, 0.566949f, 0.550556f}, {0.120638f, 0.625828f, 0.533488f},
    {0.157851f, 0.683765f, 0.501686f}, {0.246070f, 0.738910f, 0.452024f},
    {0.369214f, 0.788888f, 0.382914f}, {0.515992f, 0.831158f, 0.294279f},
    {0.678489f, 0.863742f, 0.189503f}, {0.845561f, 0.887322f, 0.099702f},
    {0.993248f, 0.906157f, 0.143936f}};

std::uint8_t to_byte(float c) {
  return std::uint8_t(std::lround(std::clamp(c, 0.0f, 1.0f) * 255.0f));
}

// Display encoding of a linear intensity (a plain 2.2 gamma).
std::uint8_t encode(float linear) {
  return to_byte(std::pow(std::clamp(linear, 0.0f, 1.0f), 1.0f / 2.2f));
}

constexpr Rgb kBackground{38, 42, 52};

float dot(const format::Float3& a, const format::Float3& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}

format::Float3 normalize(format::Float3 v) {
  const float s = 1.0f / std::sqrt(dot(v, v));
  return {v.x * s, v.y * s, v.z * s};
}

// The key light, in world space: above, left of and behind the camera (a fixed direction
// relative to the view, so every camera gets the same look).
format::Float3 key_light(const PixelRays& rays, Size size) {
  const Ray centre = rays(size.width / 2, size.height / 2);
  const Ray top = rays(size.width / 2, 0);
  const format::Float3 f = centre.dir;
  // Up on screen: the part of the top-row ray across the view direction.
  const float along = dot(top.dir, f);
  format::Float3 up{top.dir.x - f.x * along, top.dir.y - f.y * along, top.dir.z - f.z * along};
  if (!(dot(up, up) > 0)) up = {0, 1, 0};
  up = normalize(up);
  const format::Float3 right{f.y * up.z - f.z * up.y, f.z * up.x - f.x * up.z,
                             f.x * up.y - f.y * up.x};
  return normalize({-f.x * 0.6f - right.x * 0.5f + up.x * 0.8f,
                    -f.y * 0.6f - right.y * 0.5f + up.y * 0.8f,
                    -f.z * 0.6f - right.z * 0.5f + up.z * 0.8f});
}

}  // namespace

Rgb viridis(float v) {
  if (!(v > 0)) v = 0;  // NaN too
  const float x = std::min(v, 1.0f) * 255.0f;
  // Control point i sits at entry 16 i, the last at 255.
  const int i = std::min(int(x / 16.0f), 15);
  const float lo = 16.0f * float(i), hi = i == 15 ? 255.0f : lo + 16.0f;
  const float f = std::clamp((x - lo) / (hi - lo), 0.0f, 1.0f);
  float c[3];
  for (int k = 0; k < 3; ++k) c[k] = kViridis[i][k] + (kViridis[i + 1][k] - kViridis[i][k]) * f;
  return {to_byte(c[0]), to_byte(c[1]), to_byte(c[2])};
}

Rgb heat_colour(std::uint32_t cost, std::uint32_t scale) {
  if (scale == 0) scale = 1;
  const std::uint64_t steps = std::min(scale, kHeatLevels - 1);  // levels 0..steps
  const std::uint64_t level = (std::uint64_t(std::min(cost, scale)) * steps + scale / 2) / scale;
  return viridis(float(level) / float(steps));
}

std::optional<Mode> parse_mode(std::string_view name) {
  if (name == "shade") return Mode::kShade;
  if (name == "normal") return Mode::kNormal;
  if (name == "depth") return Mode::kDepth;
  if (name == "heatmap") return Mode::kHeatmap;
  return std::nullopt;
}

std::uint32_t heatmap_scale(std::span<const Samples* const> panels) {
  std::vector<std::uint32_t> costs;
  for (const Samples* p : panels)
    for (const Sample& s : p->pixels) costs.push_back(s.cost());
  if (costs.empty()) return 1;
  const std::size_t k = (costs.size() - 1) * 99 / 100;
  std::nth_element(costs.begin(), costs.begin() + std::ptrdiff_t(k), costs.end());
  return std::max<std::uint32_t>(costs[k], 1);
}

DepthRange depth_range(std::span<const Samples* const> panels) {
  DepthRange range{std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity()};
  for (const Samples* p : panels)
    for (const Sample& s : p->pixels)
      if (s.hit && std::isfinite(s.t))
        range.near = std::min(range.near, s.t), range.far = std::max(range.far, s.t);
  if (!(range.near <= range.far)) return {};
  return range;
}

Image colour(const Samples& samples, Mode mode, std::uint32_t heat_scale, DepthRange depth,
             const Camera& camera) {
  const Size size = samples.size;
  Image image(size.width, size.height, mode == Mode::kDepth ? Rgb{} : kBackground);
  const PixelRays rays(camera, size);
  const format::Float3 key = key_light(rays, size);
  const float span = depth.far > depth.near ? depth.far - depth.near : 1.0f;
  for (std::uint32_t y = 0; y < size.height; ++y)
    for (std::uint32_t x = 0; x < size.width; ++x) {
      const Sample& s = samples.pixels[std::size_t(y) * size.width + x];
      Rgb& out = image.at(x, y);
      if (mode == Mode::kHeatmap) {
        out = heat_colour(s.cost(), heat_scale);
        continue;
      }
      if (!s.hit) continue;
      const format::Float3& n = s.normal;
      switch (mode) {
        case Mode::kShade: {
          // A headlight (no surface the camera sees is black) plus the key light for shape.
          const format::Float3 d = rays(x, y).dir;
          const float head = std::max(0.0f, -dot(n, d));
          const float lit = 0.08f + 0.55f * head + 0.5f * std::max(0.0f, dot(n, key));
          out = {encode(lit * 0.92f), encode(lit * 0.88f), encode(lit * 0.80f)};
          break;
        }
        case Mode::kNormal:
          out = {to_byte(n.x * 0.5f + 0.5f), to_byte(n.y * 0.5f + 0.5f),
                 to_byte(n.z * 0.5f + 0.5f)};
          break;
        case Mode::kDepth: {
          const float v = 1.0f - 0.8f * std::clamp((s.t - depth.near) / span, 0.0f, 1.0f);
          out = {to_byte(v), to_byte(v), to_byte(v)};
          break;
        }
        case Mode::kHeatmap:
          break;
      }
    }
  return image;
}

Image side_by_side(std::span<const Image> panels) {
  std::uint32_t width = 0, height = 0;
  for (const Image& p : panels) width += p.width, height = std::max(height, p.height);
  Image out(width, height);
  std::uint32_t x0 = 0;
  for (const Image& p : panels) {
    for (std::uint32_t y = 0; y < p.height; ++y)
      std::copy_n(&p.pixels[std::size_t(y) * p.width], p.width, &out.at(x0, y));
    x0 += p.width;
  }
  return out;
}

}  // namespace kiln::render
