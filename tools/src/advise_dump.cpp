// What `kiln build --accel auto` recorded in the manifest (schema/advice.fbs), as descriptions
// for both forms of `kiln dump`.
#include <cstdio>
#include <string>

#include "dump_writers.hpp"
#include "kiln/runtime/manifest.hpp"

namespace kiln::dump {

namespace {

std::string text(const flatbuffers::String* s) {
  return s != nullptr ? s->str() : std::string();
}

DescTable rows_table(const schema::Advice& a) {
  DescTable table{"rows",
                  {"spec", "kind", "bytes", "bytes_per_triangle", "nodes_per_ray", "tests_per_ray"},
                  {}};
  if (a.rows() == nullptr) return table;
  for (const schema::AdviceRow* r : *a.rows())
    table.rows.push_back({text(r->spec()), text(r->kind()), std::uint64_t(r->bytes()),
                          r->bytes_per_triangle(), r->nodes_per_ray(), r->tests_per_ray()});
  return table;
}

std::vector<std::string> human_lines(const schema::Advice& a) {
  char line[512];
  std::vector<std::string> lines;
  std::snprintf(line, sizeof line, "%s: --accel auto (for %s, %s rays) chose %s: %s",
                text(a.structure()).c_str(), text(a.priority()).c_str(), text(a.rays()).c_str(),
                text(a.spec()).c_str(), text(a.reason()).c_str());
  lines.push_back(line);
  std::snprintf(line, sizeof line,
                "measured on %llu of %llu triangles, %llu rays per kind (seed %llu)",
                (unsigned long long)a.sample_triangles(), (unsigned long long)a.scene_triangles(),
                (unsigned long long)a.rays_per_kind(), (unsigned long long)a.seed());
  lines.push_back(line);
  std::snprintf(line, sizeof line, "  %-24s %12s %10s %10s %10s", "structure", "bytes", "bytes/tri",
                "nodes/ray", "tests/ray");
  lines.push_back(line);
  if (a.rows() != nullptr)
    for (const schema::AdviceRow* r : *a.rows()) {
      std::snprintf(line, sizeof line, "%c %-24s %12llu %10.1f %10.2f %10.2f",
                    text(r->spec()) == text(a.spec()) ? '*' : ' ', text(r->spec()).c_str(),
                    (unsigned long long)r->bytes(), r->bytes_per_triangle(), r->nodes_per_ray(),
                    r->tests_per_ray());
      lines.push_back(line);
    }
  return lines;
}

}  // namespace

std::vector<Description> describe_advice(const Blob& blob) {
  std::vector<Description> described;
  const auto* advice = manifest_of(blob).advice();
  if (advice == nullptr) return described;
  for (const schema::Advice* a : *advice) {
    Description& d = described.emplace_back();
    d.lines = human_lines(*a);
    d.field("structure", text(a->structure()))
        .field("spec", text(a->spec()))
        .field("priority", text(a->priority()))
        .field("rays", text(a->rays()))
        .field("reason", text(a->reason()))
        .field("scene_triangles", a->scene_triangles())
        .field("sample_triangles", a->sample_triangles())
        .field("rays_per_kind", a->rays_per_kind())
        .field("seed", a->seed());
    d.tables.push_back(rows_table(*a));
  }
  return described;
}

}  // namespace kiln::dump
