#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
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

constexpr std::uint32_t kWhite = 0xFFFFFFFF;
constexpr auto kUnused = std::numeric_limits<std::uint32_t>::max();

// Normals are kept only when every kept mesh has them (and there is at least one mesh).
bool every_mesh_has_normals(const std::vector<ImportedFile>& files) {
  bool every = true;
  std::size_t kept_meshes = 0;
  for (const auto& file : files)
    for (const auto& mesh : file.meshes) {
      every &= !mesh.normals.empty();
      kept_meshes += 1;
    }
  return every && kept_meshes > 0;
}

// First pass: returns the mesh's non-degenerate triangles (counting the others in `scene`) and
// sets `remap` to 0 for the vertices they use (and, in a point cloud, for every finite vertex).
std::vector<format::Triangle> keep_triangles(const ImportedMesh& mesh,
                                             const std::vector<Double3>& world,
                                             std::vector<std::uint32_t>& remap, Scene& scene) {
  remap.assign(mesh.positions.size(), kUnused);
  std::vector<format::Triangle> kept;
  kept.reserve(mesh.triangles.size());
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
  if (mesh.point_cloud)
    for (std::size_t v = 0; v < world.size(); ++v)
      if (is_finite(world[v]) && is_finite(to_float(world[v]))) remap[v] = 0;
  return kept;
}

// Second pass: appends the used vertices in their original order and sets `remap` to their scene
// ids. Colours start at the first kept vertex of a coloured mesh (the vertices before it get
// white, as do those of later meshes without colours), so a coloured mesh that keeps nothing adds
// none; `any_colors` tracks whether they started.
void append_vertices(const ImportedMesh& mesh, const std::vector<Double3>& world, bool normals,
                     std::vector<std::uint32_t>& remap, bool& any_colors, Scene& scene) {
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
    if (remap[v] == kUnused) continue;
    if (scene.positions.size() >= kUnused)
      throw ImportError(scene.sources.back().path + ": scene exceeds 2^32-1 vertices");
    if (!mesh.colors.empty() && !any_colors) {
      scene.colors.assign(scene.positions.size(), kWhite);
      any_colors = true;
    }
    if (any_colors) scene.colors.push_back(mesh.colors.empty() ? kWhite : mesh.colors[v]);
    remap[v] = std::uint32_t(scene.positions.size());
    scene.positions.push_back(to_float(world[v]));
    if (normals) scene.normals.push_back(transform_normal(mesh.transform, mesh.normals[v]));
  }
}

// Adds one mesh of file `file` to `scene`: its world-space vertices, kept triangles and entry.
void append_mesh(const ImportedMesh& mesh, std::uint32_t file, bool normals,
                 std::vector<std::uint32_t>& remap, bool& any_colors, Scene& scene) {
  SceneMesh out{mesh.name, file, scene.triangles.size(), 0, scene.positions.size(), 0};
  if (!mesh.colors.empty() && mesh.colors.size() != mesh.positions.size())
    throw ImportError(scene.sources.back().path + ": mesh '" + mesh.name + "' has " +
                      std::to_string(mesh.colors.size()) + " colours for " +
                      std::to_string(mesh.positions.size()) + " vertices");
  scene.input_triangle_count += mesh.triangles.size();
  const bool mirrored = determinant3(mesh.transform) < 0.0;
  std::vector<Double3> world(mesh.positions.size());
  for (std::size_t v = 0; v < world.size(); ++v)
    world[v] = transform_point(mesh.transform, mesh.positions[v]);
  const std::vector<format::Triangle> kept = keep_triangles(mesh, world, remap, scene);
  append_vertices(mesh, world, normals, remap, any_colors, scene);
  for (auto t : kept) {
    for (auto& v : t.v) v = remap[v];
    if (mirrored) std::swap(t.v[1], t.v[2]);  // keep the front face facing out
    scene.triangles.push_back(t);
    scene.triangle_mesh.push_back(std::uint32_t(scene.meshes.size()));
  }
  out.triangle_count = scene.triangles.size() - out.first_triangle;
  out.vertex_count = scene.positions.size() - out.first_vertex;
  scene.meshes.push_back(std::move(out));
}

}  // namespace

format::Box3f bounds_of(std::span<const format::Float3> positions) {
  format::Box3f b{{0, 0, 0}, {0, 0, 0}};
  if (positions.empty()) return b;
  b.min = b.max = positions.front();
  for (const auto& p : positions) {
    b.min = {std::min(b.min.x, p.x), std::min(b.min.y, p.y), std::min(b.min.z, p.z)};
    b.max = {std::max(b.max.x, p.x), std::max(b.max.y, p.y), std::max(b.max.z, p.z)};
  }
  return b;
}

EdgeTopology edge_topology(const Scene& scene) {
  // Weld: vertices with bit-identical positions share an id (seams split by normals or UVs
  // must not look like holes).
  const std::size_t n = scene.positions.size();
  std::vector<std::uint32_t> order(n), weld(n);
  for (std::uint32_t i = 0; i < n; ++i) order[i] = i;
  auto key = [&](std::uint32_t i) {
    const auto& p = scene.positions[i];
    std::array<std::uint32_t, 3> k;
    std::memcpy(k.data(), &p, sizeof(k));
    return k;
  };
  std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
    const auto ka = key(a), kb = key(b);
    return ka < kb || (ka == kb && a < b);
  });
  std::uint32_t id = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (i > 0 && key(order[i]) != key(order[i - 1])) ++id;
    weld[order[i]] = id;
  }
  std::vector<std::uint64_t> edges;
  edges.reserve(scene.triangles.size() * 3);
  for (const auto& t : scene.triangles)
    for (int e = 0; e < 3; ++e) {
      const std::uint64_t a = weld[t.v[e]], b = weld[t.v[(e + 1) % 3]];
      if (a != b) edges.push_back(std::min(a, b) << 32 | std::max(a, b));
    }
  std::sort(edges.begin(), edges.end());
  EdgeTopology topology;
  for (std::size_t i = 0; i < edges.size();) {
    std::size_t j = i;
    while (j < edges.size() && edges[j] == edges[i]) ++j;
    if (j - i == 1) topology.boundary_edges += 1;
    if (j - i > 2) topology.non_manifold_edges += 1;
    i = j;
  }
  return topology;
}

Scene assemble_scene(std::vector<ImportedFile> files) {
  Scene scene;
  const bool normals = every_mesh_has_normals(files);
  bool any_colors = false;
  std::vector<std::uint32_t> remap;
  for (std::uint32_t f = 0; f < files.size(); ++f) {
    ImportedFile& file = files[f];
    scene.sources.push_back(file.source);
    for (ImportedMesh& mesh : file.meshes) {
      append_mesh(mesh, f, normals, remap, any_colors, scene);
      mesh = {};  // release memory early: scenes can be large
    }
  }
  scene.bounds = bounds_of(scene.positions);
  return scene;
}

}  // namespace kiln
