// kiln_make_scene: writes a procedural scene as a binary little-endian PLY, a pure function of
// its arguments (the same bytes on every machine), without downloading anything:
//  - grids (default): many displaced grids, for builds at scale (10^7-10^8 triangles), streamed
//    out grid by grid so the generator itself needs almost no memory;
//  - uniform: small triangles scattered uniformly in a cube (uniform grids should win);
//  - stadium: the "teapot in a stadium", a dense sphere inside a huge sparse bowl (uniform grids
//    should lose badly). Both from kiln/bench/generated_scenes.hpp, built in memory.
//
//   kiln_make_scene --triangles 50000000 -o /tmp/huge.ply
//   kiln_make_scene --kind stadium --triangles 1000000 --seed 7 -o /tmp/stadium.ply
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "kiln/bench/generated_scenes.hpp"

namespace {

struct Args {
  std::uint64_t triangles = 10'000'000;
  std::uint32_t grid = 256;  // quads per grid side: 2 * grid^2 triangles per grid
  std::string kind = "grids";
  std::uint64_t seed = 1;
  std::string output;
};

void usage(std::FILE* to) {
  std::fprintf(to,
               "Usage: kiln_make_scene [--kind grids|uniform|stadium] [--triangles N] [--grid K]\n"
               "                       [--seed S] -o OUT.ply\n"
               "Writes about N triangles as a binary little-endian PLY:\n"
               "  grids    many K x K displaced grids over a lattice (rounded up to whole grids)\n"
               "  uniform  small triangles scattered uniformly in the unit cube (seeded)\n"
               "  stadium  a dense sphere (98%%) inside a huge sparse bowl: the teapot in a\n"
               "           stadium (seeded jitter)\n"
               "  --triangles N  triangles wanted (default 10000000)\n"
               "  --grid K       grids: quads per grid side, 1..4096 (default 256)\n"
               "  --seed S       uniform, stadium: the seed (default 1)\n");
}

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(arg + " needs a value");
      return argv[++i];
    };
    if (arg == "-h" || arg == "--help") {
      usage(stdout);
      std::exit(0);
    } else if (arg == "--triangles") {
      a.triangles = std::stoull(value());
    } else if (arg == "--grid") {
      a.grid = std::uint32_t(std::stoul(value()));
    } else if (arg == "--kind") {
      a.kind = value();
    } else if (arg == "--seed") {
      a.seed = std::stoull(value());
    } else if (arg == "-o" || arg == "--output") {
      a.output = value();
    } else {
      throw std::invalid_argument("unknown argument " + arg);
    }
  }
  if (a.output.empty()) throw std::invalid_argument("-o OUT.ply is required");
  if (a.grid < 1 || a.grid > 4096) throw std::invalid_argument("--grid must be 1..4096");
  if (a.kind != "grids" && a.kind != "uniform" && a.kind != "stadium")
    throw std::invalid_argument("--kind must be grids, uniform or stadium");
  if (a.triangles < 1 || a.triangles > (std::uint64_t{1} << 31))
    throw std::invalid_argument("--triangles must be 1..2^31");
  return a;
}

// A small integer hash (splitmix64), so each grid's placement is a pure function of its index.
std::uint64_t mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}
double unit(std::uint64_t h) {
  return double(h >> 11) * 0x1.0p-53;
}

class Writer {
 public:
  explicit Writer(const std::string& path) : file_(std::fopen(path.c_str(), "wb")), path_(path) {
    if (file_ == nullptr) throw std::runtime_error(path + ": cannot open for writing");
    buffer_.reserve(1 << 20);
  }
  ~Writer() {
    if (file_ != nullptr) std::fclose(file_);
  }
  template <typename T>
  void put(T value) {
    const auto* p = reinterpret_cast<const char*>(&value);  // x86-64: already little endian
    buffer_.insert(buffer_.end(), p, p + sizeof(T));
    if (buffer_.size() >= (1u << 20)) flush();
  }
  void text(const std::string& s) { buffer_.insert(buffer_.end(), s.begin(), s.end()); }
  void flush() {
    if (!buffer_.empty() && std::fwrite(buffer_.data(), 1, buffer_.size(), file_) != buffer_.size())
      throw std::runtime_error(path_ + ": write failed (disk full?)");
    buffer_.clear();
  }
  void close() {
    flush();
    if (std::fclose(std::exchange(file_, nullptr)) != 0)
      throw std::runtime_error(path_ + ": write failed");
  }

 private:
  std::FILE* file_;
  std::string path_;
  std::vector<char> buffer_;
};

// Grid g: a K x K height field of unit size, displaced by two sine waves of its own, rotated
// about a random axis and put in its own cell of a cubic lattice (cells overlap a little, so
// the BVH sees some overlap, as in real scenes).
void write_grid_vertices(Writer& out, std::uint64_t g, std::uint32_t k, std::uint32_t side) {
  const double fx = 2 + 10 * unit(mix(4 * g)), fy = 2 + 10 * unit(mix(4 * g + 1));
  const double angle = 6.283185307179586 * unit(mix(4 * g + 2));
  const double tilt = 3.141592653589793 * unit(mix(4 * g + 3));
  const double cx = double(g % side), cy = double(g / side % side), cz = double(g / side / side);
  const double ca = std::cos(angle), sa = std::sin(angle), ct = std::cos(tilt), st = std::sin(tilt);
  for (std::uint32_t j = 0; j <= k; ++j)
    for (std::uint32_t i = 0; i <= k; ++i) {
      const double u = double(i) / k - 0.5, v = double(j) / k - 0.5;
      const double h = 0.08 * std::sin(fx * u * 6.283) * std::cos(fy * v * 6.283);
      // Rotate (u, v, h) about z by angle, then about x by tilt.
      const double x = ca * u - sa * v, y0 = sa * u + ca * v;
      const double y = ct * y0 - st * h, z = st * y0 + ct * h;
      out.put(float(cx + 1.2 * x)), out.put(float(cy + 1.2 * y)), out.put(float(cz + 1.2 * z));
    }
}

void write_grid_faces(Writer& out, std::uint64_t first_vertex, std::uint32_t k) {
  const std::uint64_t row = k + 1;
  for (std::uint32_t j = 0; j < k; ++j)
    for (std::uint32_t i = 0; i < k; ++i) {
      const auto a = std::uint32_t(first_vertex + j * row + i), b = a + 1;
      const auto c = std::uint32_t(a + row), d = c + 1;
      out.put(std::uint8_t(3)), out.put(a), out.put(b), out.put(d);
      out.put(std::uint8_t(3)), out.put(a), out.put(d), out.put(c);
    }
}

// A generated scene held in memory (uniform, stadium), written whole.
void write_mesh(const Args& a, const kiln::bench::GeneratedMesh& mesh) {
  Writer out(a.output);
  out.text("ply\nformat binary_little_endian 1.0\ncomment kiln_make_scene --kind " + a.kind +
           " --triangles " + std::to_string(a.triangles) + " --seed " + std::to_string(a.seed) +
           "\nelement vertex " + std::to_string(mesh.positions.size()) +
           "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
           std::to_string(mesh.triangles.size()) +
           "\nproperty list uchar uint vertex_indices\nend_header\n");
  for (const auto& p : mesh.positions) out.put(p.x), out.put(p.y), out.put(p.z);
  for (const auto& t : mesh.triangles)
    out.put(std::uint8_t(3)), out.put(t.v[0]), out.put(t.v[1]), out.put(t.v[2]);
  out.close();
  std::fprintf(stderr, "kiln_make_scene: %s: %zu triangles, %zu vertices (%s)\n", a.output.c_str(),
               mesh.triangles.size(), mesh.positions.size(), a.kind.c_str());
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const Args a = parse(argc, argv);
    if (a.kind != "grids") {
      write_mesh(a, a.kind == "uniform" ? kiln::bench::uniform_triangles(a.triangles, a.seed)
                                        : kiln::bench::teapot_in_stadium(a.triangles, a.seed));
      return 0;
    }
    const std::uint64_t per_grid = 2ull * a.grid * a.grid;
    const std::uint64_t grids = (a.triangles + per_grid - 1) / per_grid;
    const std::uint64_t vertices = grids * (a.grid + 1ull) * (a.grid + 1ull);
    if (vertices > 0xFFFFFFFFull)
      throw std::invalid_argument("too many vertices for 32-bit indices");
    auto side = std::uint32_t(std::ceil(std::cbrt(double(grids))));
    while (std::uint64_t(side) * side * side < grids) ++side;
    Writer out(a.output);
    out.text("ply\nformat binary_little_endian 1.0\ncomment kiln_make_scene --triangles " +
             std::to_string(a.triangles) + " --grid " + std::to_string(a.grid) +
             "\nelement vertex " + std::to_string(vertices) +
             "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
             std::to_string(grids * per_grid) +
             "\nproperty list uchar uint vertex_indices\nend_header\n");
    for (std::uint64_t g = 0; g < grids; ++g) write_grid_vertices(out, g, a.grid, side);
    for (std::uint64_t g = 0; g < grids; ++g)
      write_grid_faces(out, g * (a.grid + 1ull) * (a.grid + 1ull), a.grid);
    out.close();
    std::fprintf(stderr, "kiln_make_scene: %s: %llu triangles, %llu vertices, %llu grids\n",
                 a.output.c_str(), (unsigned long long)(grids * per_grid),
                 (unsigned long long)vertices, (unsigned long long)grids);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "kiln_make_scene: %s\n", e.what());
    return 1;
  }
}
