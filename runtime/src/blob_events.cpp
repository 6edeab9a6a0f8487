// The event table input (issue 18): its checks at open and the view over its sections.
#include <algorithm>
#include <string>

#include "kiln/formats/event_table.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/manifest.hpp"

namespace kiln {

namespace {

// Times this far from zero keep every difference and bin computation inside int64.
constexpr std::int64_t kTimeLimit = std::int64_t(1) << 60;

std::string text(const flatbuffers::String* s) {
  return s ? s->str() : std::string();
}

std::uint64_t label_total(const Blob& blob, const schema::EventTable& table) {
  std::uint64_t total = 0;
  if (table.categories() == nullptr) return 0;
  for (const auto* c : *table.categories()) {
    if (c->first_label() != total)
      blob.fail_section(0, "event category labels are not consecutive");
    if (c->label_count() > (std::uint64_t(1) << 32))
      blob.fail_section(0, "event category has too many labels");
    total += c->label_count();
  }
  return total;
}

// O(rows): every code names a label, every time lies in the recorded range, offsets increase.
void check_event_columns(const Blob& blob, const schema::EventTable& table) {
  const std::uint64_t rows = table.row_count();
  if (table.time_min() > table.time_max() || table.time_min() < -kTimeLimit ||
      table.time_max() > kTimeLimit)
    blob.fail_section(0, "event time range is invalid");
  for (const std::int64_t t : blob.section_view<std::int64_t>(table.times()))
    if (t < table.time_min() || t > table.time_max())
      blob.fail_section(table.times(), "a time lies outside the recorded range");
  const auto codes = blob.section_view<std::uint32_t>(table.codes());
  if (table.categories() != nullptr)
    for (std::uint32_t c = 0; c < table.categories()->size(); ++c) {
      const std::uint64_t count = table.categories()->Get(c)->label_count();
      for (std::uint64_t r = 0; r < rows; ++r)
        if (codes[c * rows + r] >= count)
          blob.fail_section(table.codes(), "a label code is out of range");
    }
  const auto offsets = blob.section_view<std::uint64_t>(table.label_offsets());
  const auto bytes = blob.section_bytes(table.label_bytes());
  if (offsets.front() != 0 || offsets.back() != bytes.size())
    blob.fail_section(table.label_offsets(), "label offsets do not span the label bytes");
  for (std::size_t i = 1; i < offsets.size(); ++i)
    if (offsets[i] < offsets[i - 1])
      blob.fail_section(table.label_offsets(), "label offsets decrease");
}

}  // namespace

bool is_event_section_kind(std::uint32_t kind) {
  return kind == format::kSectionEventPoints || kind == format::kSectionEventTimes ||
         kind == format::kSectionEventCodes || kind == format::kSectionEventLabelOffsets ||
         kind == format::kSectionEventLabelBytes;
}

InputInfo validate_event_input(const Blob& blob, const schema::EventTable& table) {
  const std::uint64_t rows = table.row_count();
  const std::uint64_t categories = table.categories() ? table.categories()->size() : 0;
  if (rows > (std::uint64_t(1) << 40) || categories > 64)
    blob.fail_section(0, "event table is too large");
  const std::uint64_t labels = label_total(blob, table);
  blob.check_section("event points", table.points(), format::kSectionEventPoints,
                     sizeof(format::Double2), rows, false);
  blob.check_section("event times", table.times(), format::kSectionEventTimes, sizeof(std::int64_t),
                     rows, false);
  blob.check_section("event codes", table.codes(), format::kSectionEventCodes,
                     sizeof(std::uint32_t), rows * categories, false);
  blob.check_section("event label offsets", table.label_offsets(),
                     format::kSectionEventLabelOffsets, sizeof(std::uint64_t), labels + 1, false);
  if (table.label_bytes() == kNoSection || table.label_bytes() >= blob.sections().size() ||
      table.label_bytes() == 0 ||
      blob.sections()[table.label_bytes()].kind != format::kSectionEventLabelBytes ||
      blob.sections()[table.label_bytes()].element_size != 1)
    blob.fail_section(0, "manifest's event label bytes section is invalid");
  check_event_columns(blob, table);
  InputInfo info;
  info.kind = InputKind::kEvents;
  info.vertex_count = rows;
  info.feature_count = rows;
  if (const auto* b = table.bounds()) {
    info.bounds2 = {{b->min().x(), b->min().y()}, {b->max().x(), b->max().y()}};
    info.bounds = {{float(b->min().x()), float(b->min().y()), 0},
                   {float(b->max().x()), float(b->max().y()), 0}};
  }
  return info;
}

EventTableView Blob::event_table() const {
  const auto* table = manifest_of(*this).input_as_EventTable();
  if (table == nullptr) fail("the blob's input is not an event table");
  EventTableView view;
  view.points = section_view<format::Double2>(table->points());
  view.times = section_view<std::int64_t>(table->times());
  view.codes = section_view<std::uint32_t>(table->codes());
  const auto bytes = section_bytes(table->label_bytes());
  view.labels = {section_view<std::uint64_t>(table->label_offsets()),
                 {reinterpret_cast<const char*>(bytes.data()), bytes.size()}};
  if (table->categories() != nullptr)
    for (const auto* c : *table->categories()) {
      EventCategoryInfo info{
          text(c->name()), text(c->column()), {}, c->first_label(), c->label_count()};
      info.edges = copy_vector(c->edges());
      view.categories.push_back(std::move(info));
    }
  view.time_min = table->time_min(), view.time_max = table->time_max();
  view.bounds = input().bounds2;
  view.rows_skipped = table->rows_skipped();
  view.lon_column = text(table->lon_column()), view.lat_column = text(table->lat_column());
  view.time_column = text(table->time_column());
  return view;
}

std::optional<std::size_t> EventTableView::category(std::string_view name) const {
  for (std::size_t c = 0; c < categories.size(); ++c)
    if (categories[c].name == name) return c;
  return std::nullopt;
}

std::optional<std::uint32_t> EventTableView::code_of(std::size_t c, std::string_view l) const {
  for (std::uint64_t i = 0; i < categories[c].label_count; ++i)
    if (label(c, std::uint32_t(i)) == l) return std::uint32_t(i);
  return std::nullopt;
}

}  // namespace kiln
