// Vertices as Assimp's JoinIdenticalVertices left them; see join_vertices.hpp.
#include "join_vertices.hpp"

#include <algorithm>
#include <bit>

namespace kiln {

namespace {

struct JoinInput {
  const ImportedMesh* mesh;
  std::span<const std::array<float, 2>> uvs;
};

std::array<std::uint32_t, 3> position_key(const JoinInput& data, std::uint32_t v) {
  const format::Float3& p = data.mesh->positions[v];  // bits, -0 as +0
  return {std::bit_cast<std::uint32_t>(p.x + 0.0f), std::bit_cast<std::uint32_t>(p.y + 0.0f),
          std::bit_cast<std::uint32_t>(p.z + 0.0f)};
}

// Assimp's test for two vertices at the same position, in float: normals and texture
// coordinates each within 1e-5. Kiln also keeps vertices of different colours apart, and never
// joins distinct positions (Assimp did when they were within 1e-5 and its hash table happened
// to put them in one bucket).
bool joinable(const JoinInput& data, std::uint32_t a, std::uint32_t b) {
  constexpr float kEpsilon = 1e-5f;
  auto close = [&](float x, float y, float z) {
    return x * x + y * y + z * z <= kEpsilon * kEpsilon;
  };
  const ImportedMesh& mesh = *data.mesh;
  if (!mesh.colors.empty() && mesh.colors[a] != mesh.colors[b]) return false;
  if (!mesh.normals.empty()) {
    const format::Float3 &n = mesh.normals[a], &m = mesh.normals[b];
    if (!close(n.x - m.x, n.y - m.y, n.z - m.z)) return false;
  }
  return data.uvs.empty() ||
         close(data.uvs[a][0] - data.uvs[b][0], data.uvs[a][1] - data.uvs[b][1], 0.0f);
}

// At one position, in vertex order: a vertex joins the newest earlier kept vertex it is
// joinable with (the order Assimp's hash map found them in), else is kept. Only the newest
// kKeptScanned are tried, so that a hostile file cannot make this quadratic.
void join_at_position(const JoinInput& data, std::span<const std::uint32_t> group,
                      std::vector<std::uint32_t>& first, std::vector<std::uint32_t>& kept) {
  constexpr std::size_t kKeptScanned = 1024;
  kept.clear();
  for (const std::uint32_t v : group) {
    first[v] = v;
    for (std::size_t k = kept.size(); k-- > 0 && kept.size() - k <= kKeptScanned;)
      if (joinable(data, v, kept[k])) {
        first[v] = kept[k];
        break;
      }
    if (first[v] == v) kept.push_back(v);
  }
}

// For every vertex a triangle uses, the vertex it is joined to.
std::vector<std::uint32_t> joined_vertices(const JoinInput& data) {
  std::vector<std::uint32_t> first(data.mesh->positions.size(), 0);
  for (const auto& t : data.mesh->triangles)
    for (const auto v : t.v) first[v] = 1;
  std::vector<std::uint32_t> used;
  for (std::uint32_t v = 0; v < first.size(); ++v)
    if (first[v] != 0) used.push_back(v);
  std::stable_sort(used.begin(), used.end(), [&](std::uint32_t a, std::uint32_t b) {
    return position_key(data, a) < position_key(data, b);
  });
  std::vector<std::uint32_t> kept;
  for (std::size_t begin = 0, end = 0; begin < used.size(); begin = end) {
    const auto key = position_key(data, used[begin]);
    for (end = begin + 1; end < used.size() && position_key(data, used[end]) == key;) ++end;
    join_at_position(data, std::span(used).subspan(begin, end - begin), first, kept);
  }
  return first;
}

}  // namespace

void join_identical_vertices(ImportedMesh& mesh, std::span<const std::array<float, 2>> uvs) {
  const std::vector<std::uint32_t> first = joined_vertices({&mesh, uvs});
  for (auto& t : mesh.triangles)
    for (auto& v : t.v) v = first[v];
}

}  // namespace kiln
