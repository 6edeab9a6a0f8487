// The pinhole camera of `kiln render`: parsing, default framing and primary rays. Camera maths
// runs in double and rounds once to float, so every pixel's ray is the same on every run.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <numbers>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/triangle_geometry.hpp"
#include "kiln/tools/render.hpp"

namespace kiln::render {

namespace {

// A number of the whole `text` (from_chars: no locale, no leading '+' or spaces).
bool parse_number(std::string_view text, double& out) {
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
  return ec == std::errc() && end == text.data() + text.size() && std::isfinite(out);
}

bool parse_side(std::string_view text, std::uint32_t& out) {
  std::uint64_t value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || text.empty()) return false;
  out = value > kMaxImageSide ? kMaxImageSide + 1 : std::uint32_t(value);
  return true;
}

}  // namespace

std::optional<Camera> parse_camera(std::string_view text, std::string& error) {
  double v[7];
  int count = 0;
  for (std::size_t start = 0;; ++count) {
    const std::size_t comma = text.find(',', start);
    const std::string_view item = text.substr(start, comma - start);
    if (count == 7 || !parse_number(item, v[count])) {
      error = "--camera '" + std::string(text) +
              "' must be seven finite numbers: eye_x,eye_y,eye_z,target_x,target_y,target_z,"
              "fov_degrees";
      return std::nullopt;
    }
    if (comma == std::string_view::npos) {
      ++count;
      break;
    }
    start = comma + 1;
  }
  if (count != 7) {
    error = "--camera '" + std::string(text) + "' has " + std::to_string(count) +
            " numbers, not seven (eye_x,eye_y,eye_z,target_x,target_y,target_z,fov_degrees)";
    return std::nullopt;
  }
  for (const double x : v)
    if (std::fabs(x) > double(std::numeric_limits<float>::max())) {
      error = "--camera '" + std::string(text) + "': a number is out of float range";
      return std::nullopt;
    }
  Camera camera;
  camera.eye = {float(v[0]), float(v[1]), float(v[2])};
  camera.target = {float(v[3]), float(v[4]), float(v[5])};
  camera.fov_degrees = float(v[6]);
  const format::Double3 d = to_d(camera.target) - to_d(camera.eye);
  if (!(dot(d, d) > 0) || !std::isfinite(dot(d, d))) {
    error = "--camera: the eye and the target must be distinct positions";
    return std::nullopt;
  }
  if (!(v[6] > 0 && v[6] < 180)) {
    error = "--camera: the field of view must lie strictly between 0 and 180 degrees";
    return std::nullopt;
  }
  return camera;
}

std::optional<Size> parse_size(std::string_view text, std::string& error) {
  const std::size_t x = text.find_first_of("xX");
  Size size;
  if (x == std::string_view::npos || !parse_side(text.substr(0, x), size.width) ||
      !parse_side(text.substr(x + 1), size.height)) {
    error = "--size '" + std::string(text) + "' must be WIDTHxHEIGHT, e.g. 640x400";
    return std::nullopt;
  }
  if (size.width == 0 || size.height == 0 || size.width > kMaxImageSide ||
      size.height > kMaxImageSide) {
    error = "--size '" + std::string(text) + "': each side must be 1.." +
            std::to_string(kMaxImageSide) + " pixels";
    return std::nullopt;
  }
  return size;
}

Camera frame_bounds(const format::Float3& lo, const format::Float3& hi, Size size) {
  format::Double3 min = to_d(lo), max = to_d(hi);
  // A forged blob may carry non-finite bounds: frame the unit box rather than aim at NaN.
  if (!std::isfinite(dot(min, min)) || !std::isfinite(dot(max, max)))
    min = {-1, -1, -1}, max = {1, 1, 1};
  const format::Double3 centre = (min + max) * 0.5;
  double radius = std::sqrt(dot(max - min, max - min)) * 0.5;
  if (!(radius > 0) || !std::isfinite(radius)) radius = 1;
  Camera camera;
  camera.fov_degrees = 40;
  // Front (+z), right and above: shows three sides of a box, the usual "hero" view of a
  // y-up model.
  const format::Double3 direction = normalize(format::Double3{0.55, 0.4, 1.0});
  camera.target = {float(centre.x), float(centre.y), float(centre.z)};
  const format::Double3 probe = centre + direction * radius;
  camera.eye = {float(probe.x), float(probe.y), float(probe.z)};
  const PixelRays::Basis b = PixelRays(camera, size).basis();
  // Back off until all eight corners of the box project inside the frame (with a 5 % margin):
  // tighter than fitting the bounding sphere, which leaves long boxes small in the frame.
  const double tan_v = b.tan_half * 0.95, tan_h = b.tan_half * b.aspect * 0.95;
  double distance = 0;
  for (int corner = 0; corner < 8; ++corner) {
    const format::Double3 p =
        format::Double3{corner & 1 ? max.x : min.x, corner & 2 ? max.y : min.y,
                        corner & 4 ? max.z : min.z} -
        centre;
    const double depth = dot(p, b.forward);  // along the view, from the centre
    distance = std::max({distance, std::fabs(dot(p, b.right)) / tan_h - depth,
                         std::fabs(dot(p, b.up)) / tan_v - depth, -depth + 1e-3 * radius});
  }
  const format::Double3 eye = centre + direction * distance;
  camera.eye = {float(eye.x), float(eye.y), float(eye.z)};
  return camera;
}

Camera default_camera(const Blob& blob, Size size) {
  const format::Box3f& bounds = blob.input().bounds;
  return frame_bounds(bounds.min, bounds.max, size);
}

PixelRays::PixelRays(const Camera& camera, Size size) : eye_(camera.eye), size_(size) {
  Basis& b = basis_;
  b.forward = normalize(to_d(camera.target) - to_d(camera.eye));
  format::Double3 world_up{0, 1, 0};
  if (std::fabs(b.forward.y) > 0.999) world_up = {0, 0, b.forward.y > 0 ? -1.0 : 1.0};
  b.right = normalize(cross(b.forward, world_up));
  b.up = cross(b.right, b.forward);
  b.tan_half = std::tan(double(camera.fov_degrees) * std::numbers::pi / 360.0);
  b.aspect = double(size.width) / double(size.height);
}

Ray PixelRays::operator()(std::uint32_t x, std::uint32_t y) const {
  const Basis& b = basis_;
  const double px = (2.0 * (double(x) + 0.5) / double(size_.width) - 1.0) * b.tan_half * b.aspect;
  const double py = (1.0 - 2.0 * (double(y) + 0.5) / double(size_.height)) * b.tan_half;
  const format::Double3 d = normalize(b.forward + b.right * px + b.up * py);
  Ray ray;
  ray.org = eye_;
  ray.tmin = 0;
  ray.dir = {float(d.x), float(d.y), float(d.z)};
  ray.tmax = std::numeric_limits<float>::infinity();
  return ray;
}

}  // namespace kiln::render
