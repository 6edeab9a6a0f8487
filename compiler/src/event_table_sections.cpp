#include "event_table_sections.hpp"

#include <algorithm>

#include "kiln/formats/event_table.hpp"
#include "kiln/schema/manifest_generated.h"

namespace kiln {

void add_event_sections(const EventTable& table, std::vector<SectionPayload>& sections,
                        InputSectionIndices& indices) {
  auto add = [&](const SectionPayload& section) {
    sections.push_back(section);
    return std::uint32_t(sections.size() - 1);
  };
  indices.event_points = add(raw_section(format::kSectionEventPoints, table.points));
  indices.event_times = add(raw_section(format::kSectionEventTimes, table.times));
  indices.event_codes = add(raw_section(format::kSectionEventCodes, table.codes));
  indices.event_label_offsets =
      add(raw_section(format::kSectionEventLabelOffsets, table.label_offsets));
  SectionPayload bytes = {format::kSectionEventLabelBytes,
                          std::uint16_t(format::SectionFlag::kRequired),
                          1,
                          table.label_bytes.size(),
                          std::as_bytes(std::span<const char>(table.label_bytes)),
                          true};
  indices.event_label_bytes = add(bytes);
}

std::uint32_t event_table_manifest(flatbuffers::FlatBufferBuilder& fbb, const EventTable& table,
                                   const InputSectionIndices& indices) {
  std::vector<flatbuffers::Offset<schema::EventCategory>> categories;
  std::uint64_t first_label = 0;
  for (const EventCategory& c : table.categories) {
    categories.push_back(schema::CreateEventCategoryDirect(fbb, c.name.c_str(), c.column.c_str(),
                                                           &c.edges, first_label, c.labels.size()));
    first_label += c.labels.size();
  }
  format::Box2d box{{0, 0}, {0, 0}};
  if (!table.points.empty()) {
    box = {table.points.front(), table.points.front()};
    for (const auto& p : table.points)
      box.min = {std::min(box.min.x, p.x), std::min(box.min.y, p.y)},
      box.max = {std::max(box.max.x, p.x), std::max(box.max.y, p.y)};
  }
  const schema::Bounds2d bounds(schema::Vec2d(box.min.x, box.min.y),
                                schema::Vec2d(box.max.x, box.max.y));
  const auto [tmin, tmax] = std::minmax_element(table.times.begin(), table.times.end());
  return schema::CreateEventTableDirect(
             fbb, table.rows(), &bounds, table.times.empty() ? 0 : *tmin,
             table.times.empty() ? 0 : *tmax, table.rows_skipped, table.lon_column.c_str(),
             table.lat_column.c_str(), table.time_column.c_str(), &categories, indices.event_points,
             indices.event_times, indices.event_codes, indices.event_label_offsets,
             indices.event_label_bytes)
      .o;
}

}  // namespace kiln
