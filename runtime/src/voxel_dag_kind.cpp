// The sparse voxel DAG kind of the runtime registry ("dag"): its manifest checks, view, deep
// check and description.
#include <algorithm>
#include <memory>
#include <string>

#include "kiln/formats/voxel_dag.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "kiln/runtime/voxel_dag.hpp"
#include "text_format.hpp"
#include "voxel_structure.hpp"

namespace kiln {

namespace {

constexpr std::uint32_t kSections[] = {format::kSectionDagWords, format::kSectionVoxelCodes,
                                       format::kSectionVoxelNormals};

void check(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::VoxelDagDesc>(blob, info);
  const auto where = "structure '" + info.name + "' ";
  blob.check_section(where + "words", d.words(), format::kSectionDagWords, sizeof(std::uint32_t),
                     d.dag_bytes() / 4, false);
  if ((d.voxel_codes() != kNoSection) != (d.voxel_normals() != kNoSection))
    blob.fail_section(0, where + "has voxel codes without normals or the reverse");
  blob.check_section(where + "voxel codes", d.voxel_codes(), format::kSectionVoxelCodes,
                     sizeof(std::uint64_t), d.surface_voxel_count(), true);
  blob.check_section(where + "voxel normals", d.voxel_normals(), format::kSectionVoxelNormals,
                     sizeof(std::uint32_t), d.surface_voxel_count(), true);
  if (d.level_stats() == nullptr) blob.fail_section(0, where + "has no level table");
}

std::unique_ptr<StructureView> open(const Blob& blob, const StructureInfo& info) {
  return std::make_unique<VoxelStructure<VoxelDagView>>(VoxelDagView::from_blob(blob, info.name));
}

// Beyond the view's parse: the attachment's codes ascending, each naming a set voxel, one per
// voxel the manifest counts.
void verify(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::VoxelDagDesc>(blob, info);
  const VoxelDagView dag = VoxelDagView::from_blob(blob, info.name);
  const auto codes = dag.codes();
  for (std::size_t i = 0; i < codes.size(); ++i) {
    const std::uint64_t c = codes[i];
    if ((i > 0 && codes[i - 1] >= c) ||
        !dag.occupied(format::compact_bits(c), format::compact_bits(c >> 1),
                      format::compact_bits(c >> 2)))
      blob.fail_section(d.voxel_codes(), info.name + " voxel code " + std::to_string(i) +
                                             " is out of order or names an empty voxel");
  }
}

// The human level table: as printed since format 1, with the SVO/DAG ratio per level.
void describe_levels(const schema::VoxelDagDesc& d, Description& out) {
  out.lines.push_back(printf_string("%5s %14s %14s %8s %14s", "level", "SVO nodes", "DAG nodes",
                                    "SVO/DAG", "DAG bytes"));
  DescTable table{"levels_table", {"svo_nodes", "dag_nodes", "bytes"}, {}};
  const auto& levels = *d.level_stats();
  for (std::uint32_t l = 0; l < levels.size(); ++l) {
    const auto* s = levels.Get(l);
    out.lines.push_back(printf_string(
        "%5u %14llu %14llu %8.2f %14llu%s", l, (unsigned long long)s->svo_nodes(),
        (unsigned long long)s->dag_nodes(),
        double(s->svo_nodes()) / double(std::max<std::uint64_t>(1, s->dag_nodes())),
        (unsigned long long)s->bytes(), l + 1 == levels.size() ? "  (4x4x4 leaf masks)" : ""));
    table.rows.push_back({s->svo_nodes(), s->dag_nodes(), s->bytes()});
  }
  out.tables.push_back(std::move(table));
}

Description describe(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::VoxelDagDesc>(blob, info);
  const bool normals = d.voxel_normals() != kNoSection;
  const double ratio = double(d.svo_bytes()) / double(d.dag_bytes());
  Description out;
  out.lines.push_back(printf_string("%u^3 voxels of %g (origin %g, %g, %g), %llu voxels set%s",
                                    d.resolution(), d.voxel_size(), d.origin_x(), d.origin_y(),
                                    d.origin_z(), (unsigned long long)d.voxel_count(),
                                    normals ? ", normals attached" : ""));
  out.lines.push_back(printf_string("%llu DAG bytes, %.4f bits/voxel; SVO %llu bytes, SVO/DAG %.2f",
                                    (unsigned long long)d.dag_bytes(), d.bits_per_voxel(),
                                    (unsigned long long)d.svo_bytes(), ratio));
  out.field("resolution", d.resolution()).field("levels", d.levels());
  out.field("origin_x", d.origin_x()).field("origin_y", d.origin_y());
  out.field("origin_z", d.origin_z()).field("voxel_size", d.voxel_size());
  out.field("voxel_count", d.voxel_count()).field("svo_bytes", d.svo_bytes());
  out.field("dag_bytes", d.dag_bytes()).field("bits_per_voxel", d.bits_per_voxel());
  out.field("svo_dag_ratio", ratio).field("normals", normals);
  describe_levels(d, out);
  return out;
}

}  // namespace

extern const StructureKind kVoxelDagKind;

const StructureKind kVoxelDagKind{"dag",
                                  "sparse voxel DAG: rays (voxel hits), occupancy",
                                  InputKind::kTriangles,
                                  kSections,
                                  std::uint8_t(schema::StructureDesc::VoxelDagDesc),
                                  check,
                                  open,
                                  verify,
                                  describe};

}  // namespace kiln
