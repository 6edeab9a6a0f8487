// The one list of the runtime's structure kinds. Each kind is defined in its own
// <structure>_kind.cpp; registering a kind is one line here.
#include "kiln/runtime/structure_registry.hpp"

#include "kiln/runtime/blob.hpp"

namespace kiln {

extern const StructureKind kBvhKind, kSbvhKind;         // bvh_kind.cpp
extern const StructureKind kKdTreeKind;                 // kdtree_kind.cpp
extern const StructureKind kPointTreeKind;              // point_tree_kind.cpp
extern const StructureKind kVoxelDagKind;               // voxel_dag_kind.cpp
extern const StructureKind kEsvoKind;                   // esvo_kind.cpp
extern const StructureKind kOctreeKind;                 // octree_kind.cpp
extern const StructureKind kGridKind, kNestedGridKind;  // grid_kind.cpp
extern const StructureKind kNanocubeKind;               // nanocube_kind.cpp
extern const StructureKind kPolygonIndexKind;           // polygon_index_kind.cpp
extern const StructureKind kQuadtreeKind;               // quadtree_kind.cpp
extern const StructureKind kSsvdagKind;                 // ssvdag_kind.cpp

namespace {

constexpr const StructureKind* kKinds[] = {
    &kBvhKind,      &kSbvhKind,     &kKdTreeKind, &kPointTreeKind,  &kVoxelDagKind,
    &kEsvoKind,     &kOctreeKind,   &kGridKind,   &kNestedGridKind, &kPolygonIndexKind,
    &kQuadtreeKind, &kNanocubeKind, &kSsvdagKind,
};

}  // namespace

std::span<const StructureKind* const> structure_kinds() {
  return kKinds;
}

const StructureKind* find_structure_kind(std::string_view name) {
  for (const StructureKind* kind : kKinds)
    if (kind->name == name) return kind;
  return nullptr;
}

std::unique_ptr<StructureView> open_structure(const Blob& blob, std::string_view name) {
  const StructureInfo* info = blob.structure(name);
  if (info == nullptr) blob.fail("has no structure '" + std::string(name) + "'");
  // Blob::open matched every structure to a registered kind.
  return find_structure_kind(info->kind)->open(blob, *info);
}

}  // namespace kiln
