// CSV event tables: the point, time and category columns of every row (docs/FORMAT.md, "Event
// tables"). Rows keep the file's order; string labels are sorted so codes never depend on it.
#include "kiln/compiler/import_events.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>

#include "kiln/compiler/csv_reader.hpp"

namespace kiln {

namespace {

std::string shortest(double value) {
  if (std::isinf(value)) return value < 0 ? "-inf" : "inf";
  char buffer[64];
  const auto [end, ec] = std::to_chars(buffer, buffer + sizeof buffer, value);
  return std::string(buffer, ec == std::errc() ? end : buffer);
}

// Days since 1970-01-01 of a proleptic Gregorian date (Hinnant's days_from_civil).
std::int64_t days_from_civil(std::int64_t y, unsigned m, unsigned d) {
  y -= m <= 2;
  const std::int64_t era = (y >= 0 ? y : y - 399) / 400;
  const unsigned yoe = unsigned(y - era * 400);
  const unsigned doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + std::int64_t(doe) - 719468;
}

// `count` digits at `pos` as a number, or -1.
int digits(std::string_view text, std::size_t pos, std::size_t count) {
  if (pos + count > text.size()) return -1;
  int value = 0;
  for (std::size_t i = pos; i < pos + count; ++i) {
    if (text[i] < '0' || text[i] > '9') return -1;
    value = value * 10 + (text[i] - '0');
  }
  return value;
}

// "Z", "+HH:MM", "+HHMM", "+HH" at the end: the offset in seconds east of UTC.
std::optional<std::int64_t> parse_zone(std::string_view zone) {
  if (zone == "Z" || zone == "z") return 0;
  if (zone.empty() || (zone[0] != '+' && zone[0] != '-')) return std::nullopt;
  const int sign = zone[0] == '-' ? -1 : 1;
  zone.remove_prefix(1);
  const int hh = digits(zone, 0, 2);
  int mm = 0;
  if (zone.size() == 5 && zone[2] == ':')
    mm = digits(zone, 3, 2);
  else if (zone.size() == 4)
    mm = digits(zone, 2, 2);
  else if (zone.size() != 2)
    return std::nullopt;
  if (hh < 0 || hh > 23 || mm < 0 || mm > 59) return std::nullopt;
  return sign * (hh * 3600 + mm * 60);
}

std::optional<std::int64_t> parse_iso(std::string_view t) {
  const int year = digits(t, 0, 4), month = digits(t, 5, 2), day = digits(t, 8, 2);
  if (year < 0 || month < 1 || month > 12 || day < 1 || t.size() < 10 || t[4] != '-' || t[7] != '-')
    return std::nullopt;
  static constexpr int kDays[12] = {31, 29, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  const bool leap = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
  if (day > kDays[month - 1] || (month == 2 && day == 29 && !leap)) return std::nullopt;
  std::int64_t seconds = days_from_civil(year, unsigned(month), unsigned(day)) * 86400;
  if (t.size() == 10) return seconds;  // a date alone: midnight UTC
  if (t[10] != 'T' && t[10] != 't' && t[10] != ' ') return std::nullopt;
  const int hour = digits(t, 11, 2), minute = digits(t, 14, 2);
  if (hour < 0 || hour > 23 || minute < 0 || minute > 59 || t.size() < 16 || t[13] != ':')
    return std::nullopt;
  seconds += hour * 3600 + minute * 60;
  std::size_t pos = 16;
  if (pos < t.size() && t[pos] == ':') {
    const int second = digits(t, pos + 1, 2);
    if (second < 0 || second > 59) return std::nullopt;
    seconds += second;
    pos += 3;
    if (pos < t.size() && t[pos] == '.') {  // fractions of a second are truncated
      ++pos;
      const std::size_t start = pos;
      while (pos < t.size() && t[pos] >= '0' && t[pos] <= '9') ++pos;
      if (pos == start) return std::nullopt;
    }
  }
  const auto zone = parse_zone(t.substr(pos));
  if (!zone) return std::nullopt;
  return seconds - *zone;
}

}  // namespace

std::optional<std::int64_t> parse_event_time(std::string_view text) {
  while (!text.empty() && text.front() == ' ') text.remove_prefix(1);
  while (!text.empty() && text.back() == ' ') text.remove_suffix(1);
  if (text.size() > 4 && text[4] == '-') return parse_iso(text);
  std::int64_t value = 0;  // Unix seconds
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || ec != std::errc() || end != text.data() + text.size()) return std::nullopt;
  return value;
}

std::string format_event_time(std::int64_t seconds) {
  const std::int64_t days = (seconds >= 0 ? seconds : seconds - 86399) / 86400;
  const std::int64_t rest = seconds - days * 86400;
  // Hinnant's civil_from_days.
  const std::int64_t z = days + 719468;
  const std::int64_t era = (z >= 0 ? z : z - 146096) / 146097;
  const unsigned doe = unsigned(z - era * 146097);
  const unsigned yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  const unsigned doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
  const unsigned mp = (5 * doy + 2) / 153;
  const unsigned d = doy - (153 * mp + 2) / 5 + 1;
  const unsigned m = mp < 10 ? mp + 3 : mp - 9;
  const std::int64_t y = std::int64_t(yoe) + era * 400 + (m <= 2);
  char buffer[64];
  const int hh = int(rest / 3600), mm = int(rest / 60 % 60), ss = int(rest % 60);
  if (ss != 0)
    std::snprintf(buffer, sizeof buffer, "%04lld-%02u-%02uT%02d:%02d:%02dZ", (long long)y, m, d, hh,
                  mm, ss);
  else
    std::snprintf(buffer, sizeof buffer, "%04lld-%02u-%02uT%02d:%02dZ", (long long)y, m, d, hh, mm);
  return buffer;
}

EventCategorySpec parse_event_category(std::string_view text) {
  EventCategorySpec spec;
  const auto eq = text.find('=');
  spec.name = std::string(text.substr(0, eq));
  spec.column = eq == std::string_view::npos ? spec.name : std::string(text.substr(eq + 1));
  if (const auto colon = spec.column.find(':'); colon != std::string::npos) {
    std::string_view edges = std::string_view(spec.column).substr(colon + 1);
    while (!edges.empty()) {
      const auto comma = edges.find(',');
      const auto value = parse_csv_number(edges.substr(0, comma));
      if (!value || std::isnan(*value))
        throw std::invalid_argument("--category " + std::string(text) + ": '" +
                                    std::string(edges.substr(0, comma)) + "' is not a number");
      if (!spec.edges.empty() && !(*value > spec.edges.back()))
        throw std::invalid_argument("--category " + std::string(text) + ": edges must increase");
      spec.edges.push_back(*value);
      edges = comma == std::string_view::npos ? std::string_view() : edges.substr(comma + 1);
    }
    if (spec.edges.size() < 2)
      throw std::invalid_argument("--category " + std::string(text) + ": give at least 2 edges");
    spec.column.resize(colon);
  }
  if (spec.name.empty() || spec.column.empty())
    throw std::invalid_argument("--category '" + std::string(text) +
                                "': expected NAME, NAME=COLUMN or NAME=COLUMN:EDGES");
  return spec;
}

std::vector<std::string> edge_labels(const std::vector<double>& edges) {
  std::vector<std::string> labels;
  for (std::size_t i = 0; i + 1 < edges.size(); ++i) {
    const bool open_low = std::isinf(edges[i]), open_high = std::isinf(edges[i + 1]);
    if (open_low && open_high)
      labels.push_back("all");
    else if (open_low)
      labels.push_back("<" + shortest(edges[i + 1]));
    else if (open_high)
      labels.push_back(">=" + shortest(edges[i]));
    else
      labels.push_back(shortest(edges[i]) + ".." + shortest(edges[i + 1]));
  }
  return labels;
}

void index_event_labels(EventTable& table) {
  table.label_offsets.assign(1, 0);
  table.label_bytes.clear();
  for (const auto& category : table.categories)
    for (const auto& label : category.labels) {
      table.label_bytes += label;
      table.label_offsets.push_back(table.label_bytes.size());
    }
}

std::string EventColumns::key_text() const {
  std::string text = "lat=" + lat + ";lon=" + lon + ";time=" + time;
  for (const auto& c : categories) {
    text += ";category=" + c.name + "=" + c.column + ":";
    for (double e : c.edges) text += shortest(e) + ",";
  }
  text += skip_invalid ? ";skip" : "";
  return text;
}

namespace {

// The columns of each field the table needs, found in the header.
struct ColumnIndex {
  std::size_t lon = 0, lat = 0, time = 0;
  std::vector<std::size_t> categories;
  std::size_t needed = 0;  // fields a row must have
};

ColumnIndex find_columns(const CsvReader& csv, std::span<const std::string_view> header,
                         const EventColumns& columns) {
  ColumnIndex index;
  auto find = [&](const std::string& name, const char* flag) {
    if (name.empty()) throw ImportError(csv.path() + ": an event table needs " + flag + " COLUMN");
    const auto i = csv_column(header, name);
    if (!i) throw ImportError(csv.where("no column '" + name + "' (named by " + flag + ")"));
    index.needed = std::max(index.needed, *i + 1);
    return *i;
  };
  index.lon = find(columns.lon, "--lon");
  index.lat = find(columns.lat, "--lat");
  index.time = find(columns.time, "--time");
  for (const auto& c : columns.categories) index.categories.push_back(find(c.column, "--category"));
  return index;
}

// One row's values, or the reason it is bad ("column 'time': ...").
struct RowValues {
  format::Double2 point;
  std::int64_t time = 0;
  std::vector<std::uint32_t> codes;
};

std::string bad_value(const std::string& column, std::string_view value, const char* expected) {
  return "column '" + column + "': '" + std::string(value.substr(0, 64)) + "' is not " + expected;
}

// String labels get provisional codes in order of appearance (sorted at the end).
using LabelCodes = std::map<std::string, std::uint32_t, std::less<>>;

std::string parse_row(std::span<const std::string_view> fields, const ColumnIndex& index,
                      const EventColumns& columns, std::vector<LabelCodes>& labels,
                      RowValues& row) {
  if (fields.size() < index.needed)
    return std::to_string(fields.size()) + " fields, expected at least " +
           std::to_string(index.needed);
  const auto lon = parse_csv_number(fields[index.lon]), lat = parse_csv_number(fields[index.lat]);
  if (!lon || !std::isfinite(*lon) || *lon < -180 || *lon > 180)
    return bad_value(columns.lon, fields[index.lon], "a longitude in [-180, 180]");
  if (!lat || !std::isfinite(*lat) || *lat < -90 || *lat > 90)
    return bad_value(columns.lat, fields[index.lat], "a latitude in [-90, 90]");
  const auto time = parse_event_time(fields[index.time]);
  if (!time)
    return bad_value(columns.time, fields[index.time],
                     "a time (ISO 8601 with Z or an offset, or Unix seconds)");
  row.point = {*lon, *lat};
  row.time = *time;
  row.codes.clear();
  for (std::size_t c = 0; c < columns.categories.size(); ++c) {
    const auto& spec = columns.categories[c];
    const std::string_view field = fields[index.categories[c]];
    if (spec.edges.empty()) {
      auto it = labels[c].find(field);
      if (it == labels[c].end())
        it = labels[c].emplace(std::string(field), std::uint32_t(labels[c].size())).first;
      row.codes.push_back(it->second);
      continue;
    }
    const auto value = parse_csv_number(field);
    if (!value || std::isnan(*value)) return bad_value(spec.column, field, "a number");
    const auto upper = std::upper_bound(spec.edges.begin(), spec.edges.end(), *value);
    if (upper == spec.edges.begin() || upper == spec.edges.end())
      return bad_value(spec.column, field, "inside the category's edges");
    row.codes.push_back(std::uint32_t(upper - spec.edges.begin() - 1));
  }
  return {};
}

// Gives string labels codes in sorted order and rewrites the codes.
void sort_labels(EventTable& table, std::vector<LabelCodes>& labels) {
  const std::size_t rows = table.rows();
  for (std::size_t c = 0; c < table.categories.size(); ++c) {
    EventCategory& category = table.categories[c];
    if (!category.edges.empty()) {
      category.labels = edge_labels(category.edges);
      continue;
    }
    std::vector<std::uint32_t> remap(labels[c].size());
    for (const auto& [label, code] : labels[c]) {  // std::map iterates sorted
      remap[code] = std::uint32_t(category.labels.size());
      category.labels.push_back(label);
    }
    for (std::size_t r = 0; r < rows; ++r) {
      std::uint32_t& code = table.codes[c * rows + r];
      code = remap[code];
    }
  }
}

}  // namespace

EventTable read_event_csv(const std::string& path, std::string_view text,
                          const EventColumns& columns) {
  CsvReader csv(path, text);
  std::vector<std::string_view> fields;
  try {
    if (!csv.next(fields)) throw ImportError(path + ": empty CSV (no header row)");
    const std::vector<std::string> header(fields.begin(), fields.end());
    const std::vector<std::string_view> header_views(header.begin(), header.end());
    const ColumnIndex index = find_columns(csv, header_views, columns);
    EventTable table;
    table.lon_column = columns.lon, table.lat_column = columns.lat;
    table.time_column = columns.time;
    for (const auto& c : columns.categories)
      table.categories.push_back({c.name, c.column, c.edges, {}});
    std::vector<LabelCodes> labels(columns.categories.size());
    std::vector<std::vector<std::uint32_t>> codes(columns.categories.size());
    RowValues row;
    while (csv.next(fields)) {
      const std::string problem = parse_row(fields, index, columns, labels, row);
      if (!problem.empty()) {
        if (!columns.skip_invalid) throw ImportError(csv.where(problem));
        if (table.rows_skipped++ == 0) table.first_skipped = csv.where(problem);
        continue;
      }
      table.points.push_back(row.point);
      table.times.push_back(row.time);
      for (std::size_t c = 0; c < row.codes.size(); ++c) codes[c].push_back(row.codes[c]);
    }
    for (const auto& column : codes)
      table.codes.insert(table.codes.end(), column.begin(), column.end());
    sort_labels(table, labels);
    index_event_labels(table);
    if (table.rows() == 0) throw ImportError(path + ": no event rows");
    return table;
  } catch (const ImportError&) {
    throw;
  } catch (const std::runtime_error& e) {  // CsvReader's "path:LINE: ..."
    throw ImportError(e.what());
  }
}

Scene import_events(const std::string& path, const EventColumns& columns,
                    const ImportLimits& limits) {
  const InputBytes input = read_input_bytes(path, limits);
  const std::string_view text(reinterpret_cast<const char*>(input.bytes.data()),
                              input.bytes.size());
  Scene scene;
  scene.events = read_event_csv(path, text, columns);
  scene.sources.push_back(input.source);
  scene.accessed.read.push_back(path);
  normalize_accesses(scene.accessed);
  return scene;
}

Scene import_event_scene(const std::vector<std::string>& inputs, const EventColumns& columns,
                         const ImportLimits& limits) {
  if (inputs.size() != 1)
    throw ImportError(
        "an event table (--lat/--lon/--time) is read from exactly one CSV file, not " +
        std::to_string(inputs.size()));
  return import_events(inputs.front(), columns, limits);
}

}  // namespace kiln
