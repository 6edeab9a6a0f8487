// The in-memory scene the compiler builds from its inputs and writes into a blob.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "kiln/compiler/event_table.hpp"
#include "kiln/compiler/file_accesses.hpp"
#include "kiln/compiler/geo_layer.hpp"
#include "kiln/compiler/transform.hpp"
#include "kiln/formats/geometry.hpp"

namespace kiln {

// One mesh instance as an importer produces it: triangulated, in the mesh's own space with the
// instance's node transform beside it (applied by assemble_scene), indices local to this mesh.
struct ImportedMesh {
  std::string name;
  std::vector<format::Float3> positions;
  std::vector<format::Float3> normals;  // empty, or one per position
  // Empty, or one RGBA8 colour per position (r in the low byte): the vertex colour times the
  // material's base colour, or the base colour alone when the mesh has no vertex colours.
  std::vector<std::uint32_t> colors;
  std::vector<format::Triangle> triangles;
  Matrix4 transform = kIdentity;  // mesh space to world space
  // No surface, only vertices (a scan): every finite vertex is kept, not just those triangles use.
  bool point_cloud = false;
};

struct SourceFile {
  std::string path;  // as given on the command line
  std::uint64_t size = 0;
  std::uint64_t xxh3 = 0;
};

struct ImportedFile {
  SourceFile source;
  std::vector<ImportedMesh> meshes;  // in the file's documented traversal order
  FileAccesses accessed;             // the file and every companion the importer opened
};

struct SceneMesh {
  std::string name;
  std::uint32_t source_file = 0;
  std::uint64_t first_triangle = 0;
  std::uint64_t triangle_count = 0;
  std::uint64_t first_vertex = 0;
  std::uint64_t vertex_count = 0;
};

// The flattened scene: every mesh's kept triangles, in input order, with global vertex indices.
struct Scene {
  std::vector<format::Float3> positions;
  std::vector<format::Float3> normals;  // empty unless every mesh had normals
  std::vector<std::uint32_t> colors;    // empty unless some mesh had colours (others: white)
  std::vector<format::Triangle> triangles;
  std::vector<std::uint32_t> triangle_mesh;  // mesh index per triangle
  std::vector<SceneMesh> meshes;
  std::vector<SourceFile> sources;
  std::uint64_t input_triangle_count = 0;
  std::uint64_t degenerate_triangles_dropped = 0;
  format::Box3f bounds{{0, 0, 0}, {0, 0, 0}};  // all zero when empty
  FileAccesses accessed;                       // every input's, merged (import_scene fills it)
  // A 2D input instead of meshes (GeoJSON, CSV): then the arrays above are empty, and `sources`
  // and `accessed` name the one file it was read from.
  std::optional<PolygonLayer> polygons;
  std::optional<PointTable2> points2;
  // An event table (CSV with --lat/--lon/--time; issue 18): what the nanocube consumes.
  std::optional<EventTable> events;
};

// Edge manifoldness over welded positions: what "closed" means for point-inside queries.
struct EdgeTopology {
  std::uint64_t boundary_edges = 0;      // used by one triangle
  std::uint64_t non_manifold_edges = 0;  // used by three or more
  bool closed() const { return boundary_edges == 0 && non_manifold_edges == 0; }
};
EdgeTopology edge_topology(const Scene& scene);

// The box around `positions` (all zero when empty).
format::Box3f bounds_of(std::span<const format::Float3> positions);

// Concatenates imported files in order, drops degenerate triangles (zero area on the world-space
// corners evaluated in double, or a non-finite corner), drops vertices no kept triangle uses (order
// preserved; a point cloud keeps every finite vertex instead), applies each instance's transform
// (mirroring ones flip the winding), and computes the bounds. Colours follow their vertices; when
// some kept mesh has colours, the others' vertices are white. Throws ImportError when more than
// 2^32 - 1 vertices result, or a mesh has colours but not one per position.
Scene assemble_scene(std::vector<ImportedFile> files);

}  // namespace kiln
