#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "kiln/compiler/import.hpp"
#include "kiln/compiler/scene.hpp"

namespace kiln {

namespace {

bool is_finite(const Double3& p) {
  return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]);
}

// Zero area means the cross product of two edges is exactly zero, evaluated on the world-space
// corners in double, before they are rounded to float. This is the definition the corpus's
// reference counts use; a triangle that float rounding alone flattens is kept (it can never
// be hit, and dropping it would change primitive ids against every other tool's numbering).
bool is_degenerate(const Double3& a, const Double3& b, const Double3& c) {
  if (!is_finite(a) || !is_finite(b) || !is_finite(c)) return true;
  const double e1x = b[0] - a[0], e1y = b[1] - a[1], e1z = b[2] - a[2];
  const double e2x = c[0] - a[0], e2y = c[1] - a[1], e2z = c[2] - a[2];
  const double nx = e1y * e2z - e1z * e2y;
  const double ny = e1z * e2x - e1x * e2z;
  const double nz = e1x * e2y - e1y * e2x;
  return nx == 0.0 && ny == 0.0 && nz == 0.0;
}

format::Float3 to_float(const Double3& p) {
  return {float(p[0]), float(p[1]), float(p[2])};
}

bool is_finite(const format::Float3& p) {
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
}

}  // namespace

Bounds3 bounds_of(std::span<const format::Float3> positions) {
  Bounds3 b;
  if (positions.empty()) return b;
  b.min = b.max = positions.front();
  for (const auto& p : positions) {
    b.min = {std::min(b.min.x, p.x), std::min(b.min.y, p.y), std::min(b.min.z, p.z)};
    b.max = {std::max(b.max.x, p.x), std::max(b.max.y, p.y), std::max(b.max.z, p.z)};
  }
  return b;
}

Scene assemble_scene(std::vector<ImportedFile> files) {
  Scene scene;
  bool every_mesh_has_normals = true;
  std::size_t kept_meshes = 0;
  for (const auto& file : files)
    for (const auto& mesh : file.meshes) {
      every_mesh_has_normals &= !mesh.normals.empty();
      kept_meshes += 1;
    }
  every_mesh_has_normals &= kept_meshes > 0;

  std::vector<std::uint32_t> remap;
  for (std::uint32_t f = 0; f < files.size(); ++f) {
    ImportedFile& file = files[f];
    scene.sources.push_back(file.source);
    for (ImportedMesh& mesh : file.meshes) {
      SceneMesh out{mesh.name, f, scene.triangles.size(), 0, scene.positions.size(), 0};
      scene.input_triangle_count += mesh.triangles.size();
      // First pass: keep triangles, mark the vertices they use.
      constexpr auto kUnused = std::numeric_limits<std::uint32_t>::max();
      remap.assign(mesh.positions.size(), kUnused);
      std::vector<format::Triangle> kept;
      kept.reserve(mesh.triangles.size());
      const bool mirrored = determinant3(mesh.transform) < 0.0;
      std::vector<Double3> world(mesh.positions.size());
      for (std::size_t v = 0; v < world.size(); ++v)
        world[v] = transform_point(mesh.transform, mesh.positions[v]);
      for (const auto& t : mesh.triangles) {
        const auto &a = world[t.v[0]], &b = world[t.v[1]], &c = world[t.v[2]];
        if (is_degenerate(a, b, c) || !is_finite(to_float(a)) || !is_finite(to_float(b)) ||
            !is_finite(to_float(c))) {
          scene.degenerate_triangles_dropped += 1;
          continue;
        }
        kept.push_back(t);
        for (const auto v : t.v) remap[v] = 0;
      }
      // Second pass: number used vertices in their original order.
      for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
        if (remap[v] == kUnused) continue;
        if (scene.positions.size() >= kUnused)
          throw ImportError(scene.sources.back().path + ": scene exceeds 2^32-1 vertices");
        remap[v] = std::uint32_t(scene.positions.size());
        scene.positions.push_back(to_float(world[v]));
        if (every_mesh_has_normals)
          scene.normals.push_back(transform_normal(mesh.transform, mesh.normals[v]));
      }
      for (auto t : kept) {
        for (auto& v : t.v) v = remap[v];
        if (mirrored) std::swap(t.v[1], t.v[2]);  // keep the front face facing out
        scene.triangles.push_back(t);
        scene.triangle_mesh.push_back(std::uint32_t(scene.meshes.size()));
      }
      out.triangle_count = scene.triangles.size() - out.first_triangle;
      out.vertex_count = scene.positions.size() - out.first_vertex;
      scene.meshes.push_back(std::move(out));
      mesh = {};  // release memory early: scenes can be large
    }
  }

  scene.bounds = bounds_of(scene.positions);
  return scene;
}

}  // namespace kiln
