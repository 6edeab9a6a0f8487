// `kiln dump`: header, sections and manifest as text; each structure's part is its kind's
// description (its lines).
#include <algorithm>
#include <cstdio>
#include <string>
#include <variant>
#include <vector>

#include "dump_writers.hpp"
#include "kiln/formats/section_kinds.hpp"

namespace kiln::dump {

namespace {

constexpr std::size_t kMeshesShown = 32;

std::string printf_string(const char* format, auto... args) {
  char text[512];
  std::snprintf(text, sizeof(text), format, args...);
  return text;
}

void write_sections(const Blob& blob, std::ostream& out) {
  out << "sections\n";
  out << printf_string("  %3s  %-4s  %-4s  %-5s  %5s  %12s  %12s  %12s  %15s  %s\n", "#", "kind",
                       "req", "codec", "align", "offset", "stored", "raw", "elements x size",
                       "xxh3");
  for (std::uint32_t i = 0; i < blob.sections().size(); ++i) {
    const auto& s = blob.sections()[i];
    const std::string elements =
        std::to_string(s.element_count) + " x " + std::to_string(s.element_size);
    out << printf_string("  %3u  %-4s  %-4s  %-5s  %5llu  %12llu  %12llu  %12llu  %15s  %s\n", i,
                         format::fourcc_to_string(s.kind).c_str(), is_required(s) ? "yes" : "no",
                         codec_name(s.codec), 1ull << s.alignment_log2,
                         (unsigned long long)s.offset, (unsigned long long)s.stored_size,
                         (unsigned long long)s.raw_size, elements.c_str(),
                         hex64(s.checksum).c_str());
  }
}

void write_options_and_sources(const Blob& blob, std::ostream& out) {
  out << "\noptions\n";
  for (const auto& [key, value] : blob.options()) out << "  " << key << " = " << value << "\n";
  out << "\nsources\n";
  const auto sources = blob.sources();
  for (std::size_t i = 0; i < sources.size(); ++i)
    out << printf_string("  [%zu] %s  (%llu bytes, xxh3 %s)\n", i, sources[i].path.c_str(),
                         (unsigned long long)sources[i].size, hex64(sources[i].xxh3).c_str());
}

// A polygon layer's or a point table's counts, with its exact (double) bounds.
void write_geo_input(const Blob& blob, std::ostream& out) {
  const InputInfo& in = blob.input();
  out << "\ninput: " << input_kind_name(in.kind) << "\n";
  if (in.kind == InputKind::kPolygons2) {
    const PolygonLayerView layer = blob.polygon_layer();
    out << "  features   " << layer.feature_count() << "  (skipped as invalid "
        << layer.features_skipped << ", name property '" << layer.name_property << "')\n";
    out << "  polygons   " << layer.polygon_count() << "\n";
    out << "  rings      " << layer.ring_count() << "  (holes "
        << layer.ring_count() - layer.polygon_count() << ")\n";
    out << "  vertices   " << layer.vertices.size() << "\n";
  } else {
    const PointTableView table = blob.point_table();
    out << "  points     " << table.points.size() << "\n";
    out << "  rows       " << table.feature_count() << "  (skipped as invalid "
        << table.rows_skipped << ")\n";
    if (!table.x_column.empty())
      out << "  columns    x = " << table.x_column << ", y = " << table.y_column << "\n";
  }
  const auto& b = in.bounds2;
  out << printf_string("  bounds     (%.17g, %.17g) .. (%.17g, %.17g)\n", b.min.x, b.min.y, b.max.x,
                       b.max.y);
}

void write_input(const Blob& blob, std::ostream& out) {
  const InputInfo& in = blob.input();
  const auto& b = in.bounds;
  if (in.kind == InputKind::kPolygons2 || in.kind == InputKind::kPoint2)
    return write_geo_input(blob, out);
  if (in.kind == InputKind::kTriangles) {
    out << "\nscene\n";
    out << "  triangles  " << in.triangle_count << "  (imported " << in.input_triangle_count
        << ", degenerate dropped " << in.degenerate_triangles_dropped << ")\n";
    out << "  surface    " << (in.closed ? "closed" : "open") << " (" << in.boundary_edges
        << " boundary edges, " << in.non_manifold_edges << " non-manifold)\n";
    out << "  vertices   " << in.vertex_count << (in.has_normals ? "  (with normals)" : "") << "\n";
  } else {
    out << "\ninput: " << input_kind_name(in.kind) << "\n";
    out << "  count      " << in.vertex_count << "\n";
  }
  out << printf_string("  bounds     (%g, %g, %g) .. (%g, %g, %g)\n", b.min.x, b.min.y, b.min.z,
                       b.max.x, b.max.y, b.max.z);
}

void write_meshes(const Blob& blob, const DumpOptions& options, std::ostream& out) {
  const std::size_t count = blob.mesh_count();
  out << "\nmeshes (" << count << ")\n";
  out << printf_string("  %5s  %-32s  %4s  %12s  %10s  %12s  %10s\n", "#", "name", "src",
                       "first tri", "tris", "first vert", "verts");
  for (std::size_t i = 0; i < count; ++i) {
    if (!options.all_meshes && i == kMeshesShown) {
      out << "  ... " << (count - i) << " more (--all-meshes lists them)\n";
      break;
    }
    const MeshInfo m = blob.mesh(i);
    out << printf_string("  %5zu  %-32.32s  %4u  %12llu  %10llu  %12llu  %10llu\n", i,
                         m.name.c_str(), m.source_file, (unsigned long long)m.first_triangle,
                         (unsigned long long)m.triangle_count, (unsigned long long)m.first_vertex,
                         (unsigned long long)m.vertex_count);
  }
}

void write_structures(const Blob& blob, std::ostream& out) {
  out << "\nstructures\n";
  if (blob.structures().empty()) out << "  (none)\n";
  for (const StructureInfo& info : blob.structures()) {
    out << "  " << info.name << " (" << info.kind << ")\n";
    const Description d = describe(blob, info);
    for (const auto& line : d.lines) out << "    " << line << "\n";
  }
}

}  // namespace

void write_human(const Blob& blob, const DumpOptions& options, std::ostream& out) {
  const auto& h = blob.header();
  out << "kiln blob " << blob.name() << "\n";
  out << "  format " << h.version_major << "." << h.version_minor << ", " << h.file_size
      << " bytes, " << h.section_count << " sections, written by " << blob.tool_name() << " "
      << blob.tool_version() << "\n\n";
  write_sections(blob, out);
  write_options_and_sources(blob, out);
  write_input(blob, out);
  if (blob.input().kind == InputKind::kTriangles) write_meshes(blob, options, out);
  write_structures(blob, out);
  const std::vector<Description> advice = describe_advice(blob);
  if (!advice.empty()) out << "\nadvice\n";
  for (const Description& d : advice)
    for (const auto& line : d.lines) out << "  " << line << "\n";
}

}  // namespace kiln::dump
