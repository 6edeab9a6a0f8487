// The symmetry-aware sparse voxel DAG kind of the runtime registry ("ssvdag"): its manifest
// checks, view, deep check and description.
#include <algorithm>
#include <memory>
#include <string>

#include "kiln/formats/ssvdag.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/ssvdag.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "text_format.hpp"
#include "voxel_structure.hpp"

namespace kiln {

namespace {

// The node words before relative pointers (SSVN) stay listed, so such a blob is refused with the
// message below rather than as one written by a newer tool.
constexpr std::uint32_t kSections[] = {format::kSectionSsvdagNodes, format::kSectionSsvdagLeaves,
                                       format::kSectionSsvdagNodesAbsolute};

void check(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::SsvdagDesc>(blob, info);
  const auto where = "structure '" + info.name + "' ";
  if (d.nodes() < blob.sections().size() &&
      blob.sections()[d.nodes()].kind == format::kSectionSsvdagNodesAbsolute)
    blob.fail(where +
              "is an SSVDAG in the layout before relative pointers (SSVN, written before "
              "2026-11-27), which this reader no longer reads: rebuild it with kiln build "
              "and the same inputs");
  blob.check_section(where + "nodes", d.nodes(), format::kSectionSsvdagNodes, sizeof(std::uint16_t),
                     d.node_words(), false);
  blob.check_section(where + "leaves", d.leaves(), format::kSectionSsvdagLeaves,
                     sizeof(std::uint64_t), d.leaf_count(), false);
  if (d.level_stats() == nullptr) blob.fail_section(0, where + "has no level table");
}

std::unique_ptr<StructureView> open(const Blob& blob, const StructureInfo& info) {
  return std::make_unique<VoxelStructure<SsvdagView>>(SsvdagView::from_blob(blob, info.name));
}

// Beyond the view's parse: the voxels the nodes hold are as many as the manifest counts, and the
// manifest's byte count is the sections'.
void verify(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::SsvdagDesc>(blob, info);
  const SsvdagView view = SsvdagView::from_blob(blob, info.name);
  if (const std::uint64_t voxels = view.count_voxels(); voxels != d.voxel_count())
    blob.fail_section(d.nodes(), info.name + " holds " + std::to_string(voxels) +
                                     " voxels, the manifest says " +
                                     std::to_string(d.voxel_count()));
  if (d.ssvdag_bytes() != 2 * d.node_words() + 8 * d.leaf_count())
    blob.fail_section(d.nodes(), info.name + " byte count disagrees with its sections");
}

void describe_levels(const schema::SsvdagDesc& d, Description& out) {
  out.lines.push_back(printf_string("%5s %14s %14s %14s %12s %14s %12s %12s %12s", "level",
                                    "SVO nodes", "DAG nodes", "SSVDAG nodes", "by symmetry",
                                    "SSVDAG bytes", "wide ptrs", "narrow ptrs", "relative"));
  DescTable table{"levels_table",
                  {"svo_nodes", "dag_nodes", "ssvdag_nodes", "bytes", "wide_pointers",
                   "narrow_pointers", "relative_pointers"},
                  {}};
  const auto& levels = *d.level_stats();
  for (std::uint32_t l = 0; l < levels.size(); ++l) {
    const auto* s = levels.Get(l);
    out.lines.push_back(printf_string(
        "%5u %14llu %14llu %14llu %12llu %14llu %12llu %12llu %12llu%s", l,
        (unsigned long long)s->svo_nodes(), (unsigned long long)s->dag_nodes(),
        (unsigned long long)s->ssvdag_nodes(),
        (unsigned long long)(s->dag_nodes() - std::min(s->dag_nodes(), s->ssvdag_nodes())),
        (unsigned long long)s->bytes(), (unsigned long long)s->wide_pointers(),
        (unsigned long long)s->narrow_pointers(), (unsigned long long)s->relative_pointers(),
        l + 1 == levels.size() ? "  (4x4x4 leaf masks)" : ""));
    table.rows.push_back({s->svo_nodes(), s->dag_nodes(), s->ssvdag_nodes(), s->bytes(),
                          s->wide_pointers(), s->narrow_pointers(), s->relative_pointers()});
  }
  out.tables.push_back(std::move(table));
}

Description describe(const Blob& blob, const StructureInfo& info) {
  const auto& d = desc_of<schema::SsvdagDesc>(blob, info);
  const double ratio = double(d.ssvdag_bytes()) / double(std::max<std::uint64_t>(1, d.dag_bytes()));
  Description out;
  out.lines.push_back(printf_string("%u^3 voxels of %g (origin %g, %g, %g), %llu voxels set%s",
                                    d.resolution(), d.voxel_size(), d.origin_x(), d.origin_y(),
                                    d.origin_z(), (unsigned long long)d.voxel_count(),
                                    d.solid() ? ", solid" : ""));
  out.lines.push_back(printf_string(
      "%llu SSVDAG bytes, %.4f bits/voxel; the DAG of these voxels %llu bytes: SSVDAG/DAG %.3f; "
      "SVO %llu bytes",
      (unsigned long long)d.ssvdag_bytes(), d.bits_per_voxel(), (unsigned long long)d.dag_bytes(),
      ratio, (unsigned long long)d.svo_bytes()));
  out.lines.push_back(printf_string("%llu DAG nodes merged by symmetry; root mirror %u",
                                    (unsigned long long)d.symmetry_merges(), d.root_mirror()));
  out.field("resolution", d.resolution()).field("levels", d.levels());
  out.field("origin_x", d.origin_x()).field("origin_y", d.origin_y());
  out.field("origin_z", d.origin_z()).field("voxel_size", d.voxel_size());
  out.field("voxel_count", d.voxel_count()).field("svo_bytes", d.svo_bytes());
  out.field("dag_bytes", d.dag_bytes()).field("ssvdag_bytes", d.ssvdag_bytes());
  out.field("bits_per_voxel", d.bits_per_voxel()).field("ssvdag_dag_ratio", ratio);
  out.field("symmetry_merges", d.symmetry_merges()).field("root_mirror", d.root_mirror());
  out.field("solid", d.solid());
  describe_levels(d, out);
  return out;
}

}  // namespace

extern const StructureKind kSsvdagKind;

const StructureKind kSsvdagKind{"ssvdag",
                                "symmetry-aware sparse voxel DAG: rays (voxel hits), occupancy",
                                InputKind::kTriangles,
                                kSections,
                                std::uint8_t(schema::StructureDesc::SsvdagDesc),
                                check,
                                open,
                                verify,
                                describe};

}  // namespace kiln
