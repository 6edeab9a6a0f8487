// A program using a Kiln blob the way a game or a renderer would: map the blob built at build
// time, take its BVH (the structure named "bvh"), trace rays. Here: an orthographic camera above
// the scene looking down -z, one ray per character of an ASCII image, then one ray through the
// centre.
//
//   consumer [scene.kiln]     (default: the blob kiln_add_blob built beside this program)

#include <cstdio>
#include <exception>
#include <string>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/bvh_wide.hpp"
#include "kiln/runtime/ray.hpp"

namespace {

constexpr int kColumns = 24, kRows = 12;
constexpr float kCell = 0.25f;     // world units per character
constexpr float kCameraZ = 10.0f;  // the rays start on this plane

kiln::Ray down_at(float x, float y) {
  return {{x, y, kCameraZ}, 0.0f, {0.0f, 0.0f, -1.0f}, 1e30f};
}

// The name of the mesh a hit triangle came from (as the manifest records it).
std::string mesh_name(const kiln::Blob& blob, const kiln::Hit& hit) {
  const std::uint32_t mesh = blob.triangle_mesh_ids()[hit.prim];
  const std::string name = blob.mesh(mesh).name;
  return !name.empty() ? name : "mesh " + std::to_string(mesh);
}

}  // namespace

int main(int argc, char** argv) {
  const std::string path = argc > 1 ? argv[1] : KILN_CONSUMER_BLOB;
  try {
    // Maps the file and checks its structure in O(sections); the views below read the mapping.
    const kiln::Blob blob = kiln::Blob::open_file(path);
    // `--accel bvh` stores the wide layout by default (kiln::BvhView reads --bvh-width 2 blobs;
    // kiln::open_structure opens either without naming the layout).
    const kiln::BvhWideView bvh = kiln::BvhWideView::from_blob(blob, "bvh");
    std::printf("%s: %zu meshes, %zu triangles\n", path.c_str(), blob.mesh_count(),
                blob.triangles().size());

    // One ray through the centre of each character cell: '#' the box, '+' the backdrop.
    int hits = 0;
    for (int row = 0; row < kRows; ++row) {
      std::string line;
      for (int col = 0; col < kColumns; ++col) {
        const float x = (col - kColumns / 2 + 0.5f) * kCell;
        const float y = (kRows / 2 - row - 0.5f) * kCell;
        const kiln::Hit hit = bvh.intersect(down_at(x, y));
        if (!hit.hit()) {
          line += '.';
        } else {
          ++hits;
          line += mesh_name(blob, hit) == "box" ? '#' : '+';
        }
      }
      std::printf("%s\n", line.c_str());
    }
    std::printf("hits: %d of %d\n", hits, kColumns * kRows);

    const kiln::Hit centre = bvh.intersect(down_at(0.0f, 0.0f));
    if (!centre.hit()) {
      std::printf("centre: miss\n");
    } else {
      std::printf("centre: t = %.3f on %s\n", centre.t, mesh_name(blob, centre).c_str());
    }
    return 0;
  } catch (const std::exception& e) {  // kiln::BlobError: unreadable or malformed blob
    std::fprintf(stderr, "consumer: %s\n", e.what());
    return 1;
  }
}
