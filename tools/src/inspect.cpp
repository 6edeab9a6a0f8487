#include "kiln/tools/inspect.hpp"

#include <cinttypes>
#include <cstdio>
#include <string>

#include "kiln/formats/section_kinds.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/tools/json_writer.hpp"

namespace kiln {

namespace {

constexpr std::size_t kMeshesShown = 32;

std::string hex64(std::uint64_t value) {
  char text[20];
  std::snprintf(text, sizeof(text), "%016" PRIx64, value);
  return text;
}

const char* codec_name(std::uint8_t codec) {
  switch (format::Codec(codec)) {
    case format::Codec::kNone:
      return "none";
    case format::Codec::kZstd:
      return "zstd";
  }
  return "?";
}

std::string str(const flatbuffers::String* s) {
  return s ? s->str() : std::string();
}

std::string printf_string(const char* format, auto... args) {
  char text[512];
  std::snprintf(text, sizeof(text), format, args...);
  return text;
}

void write_json(const Blob& blob, std::ostream& out) {
  const auto& h = blob.header();
  const auto& m = blob.manifest();
  JsonWriter j(out);
  j.begin_object();
  j.field("file", blob.name());
  j.key("header").begin_object();
  j.field("version", std::to_string(h.version_major) + "." + std::to_string(h.version_minor));
  j.field("header_size", h.header_size).field("flags", h.flags).field("file_size", h.file_size);
  j.field("section_table_offset", h.section_table_offset).field("section_count", h.section_count);
  j.field("section_entry_size", h.section_entry_size);
  j.field("section_table_checksum", hex64(h.section_table_checksum));
  j.field("header_checksum", hex64(h.header_checksum));
  j.end_object();

  j.key("sections").begin_array();
  for (const auto& s : blob.sections()) {
    j.begin_object();
    j.field("kind", format::fourcc_to_string(s.kind));
    j.field("required", (s.flags & std::uint16_t(format::SectionFlag::kRequired)) != 0);
    j.field("codec", codec_name(s.codec));
    j.field("alignment", std::uint64_t{1} << s.alignment_log2);
    j.field("offset", s.offset).field("stored_size", s.stored_size).field("raw_size", s.raw_size);
    j.field("element_count", s.element_count).field("element_size", s.element_size);
    j.field("xxh3", hex64(s.checksum));
    j.end_object();
  }
  j.end_array();

  j.key("manifest").begin_object();
  j.field("tool_name", str(m.tool_name())).field("tool_version", str(m.tool_version()));
  j.key("options").begin_object();
  if (m.options())
    for (const auto* o : *m.options()) j.field(o->key()->str(), o->value()->str());
  j.end_object();
  j.key("sources").begin_array();
  if (m.sources())
    for (const auto* s : *m.sources())
      j.begin_object()
          .field("path", str(s->path()))
          .field("size", s->size())
          .field("xxh3", hex64(s->xxh3()))
          .end_object();
  j.end_array();
  const auto* scene = m.scene();
  const auto& b = *scene->bounds();
  j.key("scene").begin_object();
  j.field("vertex_count", scene->vertex_count()).field("triangle_count", scene->triangle_count());
  j.field("input_triangle_count", scene->input_triangle_count());
  j.field("degenerate_triangles_dropped", scene->degenerate_triangles_dropped());
  j.field("has_normals", scene->has_normals());
  j.field("closed", scene->closed()).field("boundary_edges", scene->boundary_edges());
  j.field("non_manifold_edges", scene->non_manifold_edges());
  j.field("mesh_count", std::uint64_t(m.meshes() ? m.meshes()->size() : 0));
  j.key("bounds").begin_object();
  j.key("min")
      .begin_array()
      .value(double(b.min().x()))
      .value(double(b.min().y()))
      .value(double(b.min().z()))
      .end_array();
  j.key("max")
      .begin_array()
      .value(double(b.max().x()))
      .value(double(b.max().y()))
      .value(double(b.max().z()))
      .end_array();
  j.end_object();
  j.end_object();
  j.key("meshes").begin_array();
  if (m.meshes())
    for (const auto* mesh : *m.meshes()) {
      j.begin_object().field("name", str(mesh->name())).field("source_file", mesh->source_file());
      j.field("first_triangle", mesh->first_triangle())
          .field("triangle_count", mesh->triangle_count());
      j.field("first_vertex", mesh->first_vertex()).field("vertex_count", mesh->vertex_count());
      j.end_object();
    }
  j.end_array();
  const auto* g = m.geometry();
  auto section_or_null = [&](const char* name, std::uint32_t index) {
    j.key(name);
    if (index == kNoSection)
      j.null();
    else
      j.value(index);
  };
  j.key("geometry").begin_object();
  section_or_null("positions", g->positions());
  section_or_null("triangles", g->triangles());
  section_or_null("triangle_mesh", g->triangle_mesh());
  section_or_null("normals", g->normals());
  j.end_object();
  j.key("accelerations").begin_array();
  if (m.accelerations())
    for (const auto* a : *m.accelerations()) {
      j.begin_object().field("kind", str(a->kind()));
      j.key("sections").begin_array();
      if (a->sections())
        for (const auto index : *a->sections()) j.value(index);
      j.end_array();
      if (const auto* b = a->bvh()) {
        j.key("bvh").begin_object();
        j.field("builder", str(b->builder())).field("bins", b->bins());
        j.field("traversal_cost", double(b->traversal_cost()));
        j.field("intersection_cost", double(b->intersection_cost()));
        j.field("max_leaf_size", b->max_leaf_size()).field("sbvh_alpha", double(b->sbvh_alpha()));
        j.field("sbvh_max_duplication", double(b->sbvh_max_duplication()));
        j.field("node_count", b->node_count()).field("leaf_count", b->leaf_count());
        j.field("reference_count", b->reference_count()).field("max_depth", b->max_depth());
        j.field("largest_leaf", b->largest_leaf())
            .field("average_leaf_size", b->average_leaf_size());
        j.field("duplication_factor", b->duplication_factor()).field("sah_cost", b->sah_cost());
        j.field("bytes_per_triangle", b->bytes_per_triangle());
        j.end_object();
      }
      if (const auto* k = a->kdtree()) {
        j.key("kdtree").begin_object();
        j.field("traversal_cost", double(k->traversal_cost()));
        j.field("intersection_cost", double(k->intersection_cost()));
        j.field("empty_bonus", double(k->empty_bonus())).field("depth_limit", k->depth_limit());
        j.field("node_count", k->node_count()).field("leaf_count", k->leaf_count());
        j.field("empty_leaf_count", k->empty_leaf_count());
        j.field("reference_count", k->reference_count()).field("max_depth", k->max_depth());
        j.field("largest_leaf", k->largest_leaf());
        j.field("references_per_triangle", k->references_per_triangle());
        j.field("sah_cost", k->sah_cost()).field("bytes_per_triangle", k->bytes_per_triangle());
        j.end_object();
      }
      if (const auto* d = a->dag()) {
        j.key("dag").begin_object();
        j.field("resolution", d->resolution()).field("levels", d->levels());
        j.field("origin_x", d->origin_x()).field("origin_y", d->origin_y());
        j.field("origin_z", d->origin_z()).field("voxel_size", d->voxel_size());
        j.field("voxel_count", d->voxel_count()).field("svo_bytes", d->svo_bytes());
        j.field("dag_bytes", d->dag_bytes()).field("bits_per_voxel", d->bits_per_voxel());
        j.field("svo_dag_ratio", double(d->svo_bytes()) / double(d->dag_bytes()));
        j.field("normals", d->voxel_normals() != kNoSection);
        j.key("levels_table").begin_array();
        if (d->level_stats())
          for (const auto* l : *d->level_stats()) {
            j.begin_object().field("svo_nodes", l->svo_nodes()).field("dag_nodes", l->dag_nodes());
            j.field("bytes", l->bytes()).end_object();
          }
        j.end_array();
        j.end_object();
      }
      if (const auto* e = a->esvo()) {
        const double leaves = double(std::max<std::uint64_t>(1, e->leaf_count()));
        j.key("esvo").begin_object();
        j.field("resolution", e->resolution()).field("levels", e->levels());
        j.field("origin_x", e->origin_x()).field("origin_y", e->origin_y());
        j.field("origin_z", e->origin_z()).field("voxel_size", e->voxel_size());
        j.field("contours", e->contours()).field("error_bound_voxels", e->error_bound_voxels());
        j.field("colors", e->colors() != kNoSection);
        j.field("descriptor_count", e->descriptor_count()).field("voxel_count", e->voxel_count());
        j.field("leaf_count", e->leaf_count()).field("contour_count", e->contour_count());
        j.field("far_pointer_count", e->far_pointer_count()).field("max_depth", e->max_depth());
        j.field("block_count", e->block_count()).field("word_count", e->word_count());
        j.field("hierarchy_bytes", e->hierarchy_bytes());
        j.field("contour_bytes", e->contour_bytes());
        j.field("attachment_bytes", e->attachment_bytes());
        j.field("bytes_per_leaf", e->bytes_per_leaf());
        j.field("hierarchy_bytes_per_leaf", double(e->hierarchy_bytes()) / leaves);
        j.field("contour_bytes_per_leaf", double(e->contour_bytes()) / leaves);
        j.field("attachment_bytes_per_leaf", double(e->attachment_bytes()) / leaves);
        j.key("levels_table").begin_array();
        if (e->level_stats())
          for (const auto* l : *e->level_stats()) {
            j.begin_object().field("descriptors", l->descriptors()).field("voxels", l->voxels());
            j.field("leaves", l->leaves()).field("contours", l->contours()).end_object();
          }
        j.end_array();
        j.end_object();
      }
      if (const auto* p = a->points()) {
        j.key("points").begin_object();
        j.field("split_rule", str(p->split_rule())).field("max_leaf_size", p->max_leaf_size());
        j.field("point_count", p->point_count()).field("node_count", p->node_count());
        j.field("leaf_count", p->leaf_count()).field("max_depth", p->max_depth());
        j.field("largest_leaf", p->largest_leaf()).field("bytes_per_point", p->bytes_per_point());
        j.end_object();
      }
      j.end_object();
    }
  j.end_array();
  j.end_object();
  j.end_object();
  out << '\n';
}

void write_human(const Blob& blob, const DumpOptions& options, std::ostream& out) {
  const auto& h = blob.header();
  const auto& m = blob.manifest();
  out << "kiln blob " << blob.name() << "\n";
  out << "  format " << h.version_major << "." << h.version_minor << ", " << h.file_size
      << " bytes, " << h.section_count << " sections, written by " << str(m.tool_name()) << " "
      << str(m.tool_version()) << "\n\n";
  out << "sections\n";
  out << printf_string("  %3s  %-4s  %-4s  %-5s  %5s  %12s  %12s  %12s  %15s  %s\n", "#", "kind",
                       "req", "codec", "align", "offset", "stored", "raw", "elements x size",
                       "xxh3");
  for (std::uint32_t i = 0; i < blob.sections().size(); ++i) {
    const auto& s = blob.sections()[i];
    const std::string elements =
        std::to_string(s.element_count) + " x " + std::to_string(s.element_size);
    out << printf_string("  %3u  %-4s  %-4s  %-5s  %5llu  %12llu  %12llu  %12llu  %15s  %s\n", i,
                         format::fourcc_to_string(s.kind).c_str(),
                         (s.flags & std::uint16_t(format::SectionFlag::kRequired)) ? "yes" : "no",
                         codec_name(s.codec), 1ull << s.alignment_log2,
                         (unsigned long long)s.offset, (unsigned long long)s.stored_size,
                         (unsigned long long)s.raw_size, elements.c_str(),
                         hex64(s.checksum).c_str());
  }
  out << "\noptions\n";
  if (m.options())
    for (const auto* o : *m.options())
      out << "  " << o->key()->str() << " = " << o->value()->str() << "\n";
  out << "\nsources\n";
  if (m.sources())
    for (std::uint32_t i = 0; i < m.sources()->size(); ++i) {
      const auto* s = m.sources()->Get(i);
      out << printf_string("  [%u] %s  (%llu bytes, xxh3 %s)\n", i, str(s->path()).c_str(),
                           (unsigned long long)s->size(), hex64(s->xxh3()).c_str());
    }
  const auto* scene = m.scene();
  const auto& b = *scene->bounds();
  out << "\nscene\n";
  out << "  triangles  " << scene->triangle_count() << "  (imported "
      << scene->input_triangle_count() << ", degenerate dropped "
      << scene->degenerate_triangles_dropped() << ")\n";
  out << "  surface    " << (scene->closed() ? "closed" : "open") << " (" << scene->boundary_edges()
      << " boundary edges, " << scene->non_manifold_edges() << " non-manifold)\n";
  out << "  vertices   " << scene->vertex_count()
      << (scene->has_normals() ? "  (with normals)" : "") << "\n";
  out << printf_string("  bounds     (%g, %g, %g) .. (%g, %g, %g)\n", b.min().x(), b.min().y(),
                       b.min().z(), b.max().x(), b.max().y(), b.max().z());
  const std::size_t mesh_count = m.meshes() ? m.meshes()->size() : 0;
  out << "\nmeshes (" << mesh_count << ")\n";
  out << printf_string("  %5s  %-32s  %4s  %12s  %10s  %12s  %10s\n", "#", "name", "src",
                       "first tri", "tris", "first vert", "verts");
  for (std::size_t i = 0; i < mesh_count; ++i) {
    if (!options.all_meshes && i == kMeshesShown) {
      out << "  ... " << (mesh_count - i) << " more (--all-meshes lists them)\n";
      break;
    }
    const auto* mesh = m.meshes()->Get(std::uint32_t(i));
    out << printf_string(
        "  %5zu  %-32.32s  %4u  %12llu  %10llu  %12llu  %10llu\n", i, str(mesh->name()).c_str(),
        mesh->source_file(), (unsigned long long)mesh->first_triangle(),
        (unsigned long long)mesh->triangle_count(), (unsigned long long)mesh->first_vertex(),
        (unsigned long long)mesh->vertex_count());
  }
  out << "\naccelerations\n";
  if (!m.accelerations() || m.accelerations()->size() == 0)
    out << "  (none)\n";
  else
    for (const auto* a : *m.accelerations()) {
      out << "  " << str(a->kind()) << "\n";
      if (const auto* b = a->bvh()) {
        out << printf_string("    builder %s, %u bins, max leaf %u, SAH constants Ct %g Ci %g",
                             str(b->builder()).c_str(), b->bins(), b->max_leaf_size(),
                             double(b->traversal_cost()), double(b->intersection_cost()));
        if (str(b->builder()) == "sbvh")
          out << printf_string(", alpha %g, max duplication %g", double(b->sbvh_alpha()),
                               double(b->sbvh_max_duplication()));
        out << printf_string(
            "\n    %llu nodes, %llu leaves, depth %u, leaf size avg %.2f max %u\n"
            "    %llu references (%.3f per triangle), SAH cost %.3f, %.1f bytes/triangle\n",
            (unsigned long long)b->node_count(), (unsigned long long)b->leaf_count(),
            b->max_depth(), b->average_leaf_size(), b->largest_leaf(),
            (unsigned long long)b->reference_count(), b->duplication_factor(), b->sah_cost(),
            b->bytes_per_triangle());
      }
      if (const auto* k = a->kdtree()) {
        out << printf_string(
            "    SAH constants Ct %g Ci %g, empty bonus %g, depth limit %u\n"
            "    %llu nodes, %llu leaves (%llu empty), depth %u, largest leaf %u\n"
            "    %llu references (%.3f per triangle), SAH cost %.3f, %.1f bytes/triangle\n",
            double(k->traversal_cost()), double(k->intersection_cost()), double(k->empty_bonus()),
            k->depth_limit(), (unsigned long long)k->node_count(),
            (unsigned long long)k->leaf_count(), (unsigned long long)k->empty_leaf_count(),
            k->max_depth(), k->largest_leaf(), (unsigned long long)k->reference_count(),
            k->references_per_triangle(), k->sah_cost(), k->bytes_per_triangle());
      }
      if (const auto* d = a->dag()) {
        out << printf_string(
            "    %u^3 voxels of %g (origin %g, %g, %g), %llu voxels set%s\n"
            "    %llu DAG bytes, %.4f bits/voxel; SVO %llu bytes, SVO/DAG %.2f\n"
            "    %5s %14s %14s %8s %14s\n",
            d->resolution(), d->voxel_size(), d->origin_x(), d->origin_y(), d->origin_z(),
            (unsigned long long)d->voxel_count(),
            d->voxel_normals() != kNoSection ? ", normals attached" : "",
            (unsigned long long)d->dag_bytes(), d->bits_per_voxel(),
            (unsigned long long)d->svo_bytes(), double(d->svo_bytes()) / double(d->dag_bytes()),
            "level", "SVO nodes", "DAG nodes", "SVO/DAG", "DAG bytes");
        if (d->level_stats())
          for (std::uint32_t l = 0; l < d->level_stats()->size(); ++l) {
            const auto* s = d->level_stats()->Get(l);
            out << printf_string(
                "    %5u %14llu %14llu %8.2f %14llu%s\n", l, (unsigned long long)s->svo_nodes(),
                (unsigned long long)s->dag_nodes(),
                double(s->svo_nodes()) / double(std::max<std::uint64_t>(1, s->dag_nodes())),
                (unsigned long long)s->bytes(),
                l + 1 == d->level_stats()->size() ? "  (4x4x4 leaf masks)" : "");
          }
      }
      if (const auto* e = a->esvo()) {
        const double leaves = double(std::max<std::uint64_t>(1, e->leaf_count()));
        out << printf_string(
            "    %u^3 finest voxels of %g (origin %g, %g, %g), %s, every hit within %.3f voxels "
            "of the surface\n"
            "    %llu descriptors, %llu voxels, %llu leaves (deepest at level %u), %llu contours, "
            "%llu far pointers, %llu blocks\n"
            "    %.2f bytes/leaf: hierarchy %.2f, contours %.2f, attachments %.2f (normals%s)\n"
            "    %5s %14s %14s %14s %14s\n",
            e->resolution(), e->voxel_size(), e->origin_x(), e->origin_y(), e->origin_z(),
            e->contours() ? "contours" : "no contours (cubes)", e->error_bound_voxels(),
            (unsigned long long)e->descriptor_count(), (unsigned long long)e->voxel_count(),
            (unsigned long long)e->leaf_count(), e->max_depth(),
            (unsigned long long)e->contour_count(), (unsigned long long)e->far_pointer_count(),
            (unsigned long long)e->block_count(), e->bytes_per_leaf(),
            double(e->hierarchy_bytes()) / leaves, double(e->contour_bytes()) / leaves,
            double(e->attachment_bytes()) / leaves, e->colors() != kNoSection ? ", colours" : "",
            "level", "descriptors", "voxels", "leaves", "contours");
        if (e->level_stats())
          for (std::uint32_t l = 0; l < e->level_stats()->size(); ++l) {
            const auto* s = e->level_stats()->Get(l);
            if (s->descriptors() == 0) continue;
            out << printf_string("    %5u %14llu %14llu %14llu %14llu\n", l,
                                 (unsigned long long)s->descriptors(),
                                 (unsigned long long)s->voxels(), (unsigned long long)s->leaves(),
                                 (unsigned long long)s->contours());
          }
      }
      if (const auto* p = a->points()) {
        out << printf_string(
            "    %s splits, max leaf %u\n"
            "    %llu points, %llu nodes, %llu leaves, depth %u, largest leaf %u, %.1f "
            "bytes/point\n",
            str(p->split_rule()).c_str(), p->max_leaf_size(), (unsigned long long)p->point_count(),
            (unsigned long long)p->node_count(), (unsigned long long)p->leaf_count(),
            p->max_depth(), p->largest_leaf(), p->bytes_per_point());
      }
    }
}

}  // namespace

int run_dump(const std::string& path, const DumpOptions& options, std::ostream& out,
             std::ostream& err) {
  std::string error;
  const auto blob = Blob::try_open_file(path, error);
  if (!blob) {
    err << "kiln dump: " << error << "\n";
    return 1;
  }
  if (options.json)
    write_json(*blob, out);
  else
    write_human(*blob, options, out);
  return 0;
}

int run_verify(const std::string& path, bool json, std::ostream& out, std::ostream& err) {
  std::string error;
  auto blob = Blob::try_open_file(path, error);
  if (blob) {
    try {
      blob->verify();
    } catch (const BlobError& e) {
      error = e.what();
    }
  }
  if (json) {
    JsonWriter j(out);
    j.begin_object().field("file", path).field("ok", error.empty());
    if (!error.empty()) j.field("error", error);
    j.end_object();
    out << "\n";
  } else if (error.empty()) {
    out << "ok: " << path << " (" << blob->sections().size() << " sections, "
        << blob->header().file_size << " bytes, all checksums match)\n";
  }
  if (!error.empty()) {
    err << "kiln verify: " << error << "\n";
    return 1;
  }
  return 0;
}

}  // namespace kiln
