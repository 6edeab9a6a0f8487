// Opening the served blobs and describing them (the stats of `kiln dump --json`, without the
// server's file paths, plus what the page needs of an event table: categories, time, bounds).
#include "serve_catalog.hpp"

#include <filesystem>
#include <sstream>
#include <stdexcept>

#include "../src/dump_writers.hpp"
#include "kiln/runtime/nanocube.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "kiln/tools/query_json.hpp"

namespace kiln::serve {

namespace {

using nlohmann::json;

json bounds_json(const format::Box2d& b) {
  return json::array({b.min.x, b.min.y, b.max.x, b.max.y});
}

// An event table's categories with their labels, time range and bounds (the page's controls).
json events_json(const Blob& blob, const StructureView* cube) {
  const EventTableView table = blob.event_table();
  json categories = json::array();
  for (std::size_t c = 0; c < table.categories.size(); ++c) {
    json labels = json::array();
    for (std::uint32_t l = 0; l < table.categories[c].label_count; ++l)
      labels.push_back(std::string(table.label(c, l)));
    categories.push_back({{"name", table.categories[c].name}, {"labels", std::move(labels)}});
  }
  json e = {{"rows", table.rows()},
            {"time_min", table.time_min},
            {"time_max", table.time_max},
            {"bounds", bounds_json(table.bounds)},
            {"categories", std::move(categories)}};
  if (cube && cube->events()) {
    e["time_bin"] = cube->events()->time_bin();
    e["finest_level"] = cube->events()->finest_level();
  }
  return e;
}

// What `kiln dump --json` says of the blob's input and structures (its manifest part).
json dump_of(const Blob& blob) {
  std::ostringstream text;
  dump::write_json(blob, text);
  json manifest = json::parse(text.str()).at("manifest");
  manifest.erase("sources");  // the server's paths are nobody's business
  return manifest;
}

ServedBlob open_blob(const std::string& path) {
  ServedBlob served;
  served.name = blob_name(path);
  served.blob = std::make_unique<Blob>(Blob::open_file(path));
  const Blob& blob = *served.blob;
  for (const StructureInfo& info : blob.structures())
    served.structures.emplace_back(info.name, open_structure(blob, info.name));
  json manifest = dump_of(blob);
  served.info = {{"name", served.name}, {"input", manifest.at("input")}};
  for (const char* key : {"scene", "polygon_layer", "point_table", "point_set"})
    if (manifest.contains(key)) served.info[key] = manifest.at(key);
  json structures = json::array();
  const StructureView* cube = nullptr;
  for (std::size_t i = 0; i < served.structures.size(); ++i) {
    const json& s = manifest.at("structures").at(i);
    json entry = {{"name", s.at("name")}, {"kind", s.at("kind")}};
    if (s.contains(s.at("kind").get<std::string>()))
      entry["stats"] = s.at(s.at("kind").get<std::string>());
    structures.push_back(std::move(entry));
    if (!cube && served.structures[i].second->events()) cube = served.structures[i].second.get();
  }
  served.info["structures"] = std::move(structures);
  if (blob.input().kind == InputKind::kEvents) served.info["events"] = events_json(blob, cube);
  return served;
}

}  // namespace

std::string blob_name(const std::string& path) {
  std::string name = std::filesystem::path(path).filename().string();
  if (name.size() > 5 && name.ends_with(".kiln")) name.resize(name.size() - 5);
  return name;
}

const StructureView* ServedBlob::structure(std::string_view name, std::string_view op) const {
  for (const auto& [n, view] : structures) {
    if (!name.empty() && n == name) return view.get();
    if (name.empty() && view_answers(*view, op)) return view.get();
  }
  return nullptr;
}

Catalog::Catalog(const std::vector<std::string>& paths) {
  for (const std::string& path : paths) {
    ServedBlob served = open_blob(path);
    if (find(served.name))
      throw std::runtime_error(path + ": a blob named '" + served.name + "' is already served");
    blobs_.push_back(std::move(served));
  }
}

const ServedBlob* Catalog::find(std::string_view name) const {
  if (name.empty()) return blobs_.size() == 1 ? &blobs_[0] : nullptr;
  for (const ServedBlob& b : blobs_)
    if (b.name == name) return &b;
  return nullptr;
}

json Catalog::describe() const {
  json blobs = json::array();
  for (const ServedBlob& b : blobs_) blobs.push_back(b.info);
  return {{"blobs", std::move(blobs)}};
}

}  // namespace kiln::serve
