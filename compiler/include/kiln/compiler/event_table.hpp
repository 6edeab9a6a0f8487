// The in-memory event table (issue 18): one row per event with a point (longitude, latitude),
// a time (Unix seconds) and one label code per categorical dimension; read from CSV by
// import_events, written to a blob as raw columns, consumed by the nanocube.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "kiln/formats/vector.hpp"

namespace kiln {

/// One categorical dimension as asked for on the command line: `--category origin` (a string
/// column, labels sorted by byte value) or `--category delay=delay_min:-inf,0,15,60,inf` (a
/// numeric column cut at the edges: class i is [edges[i], edges[i+1])).
struct EventCategorySpec {
  std::string name;
  std::string column;
  std::vector<double> edges;  ///< empty for a string column; else at least 2, increasing
};

/// What makes a CSV an event table: the columns `--lat`, `--lon`, `--time`, the categories.
struct EventColumns {
  std::string lat, lon, time;
  std::vector<EventCategorySpec> categories;
  bool skip_invalid = false;  ///< drop (and count) bad rows instead of failing
  bool active() const { return !lat.empty() || !lon.empty() || !time.empty(); }
  /// Canonical text for the build cache key.
  std::string key_text() const;
};

/// Parses `NAME`, `NAME=COLUMN` or `NAME=COLUMN:E0,E1,...` (edges may be -inf/inf). Throws
/// std::invalid_argument with one line.
EventCategorySpec parse_event_category(std::string_view text);

/// The labels of numeric classes: "<15", "15..60", ">=60" (edges printed shortest).
std::vector<std::string> edge_labels(const std::vector<double>& edges);

/// A time as Unix seconds: ISO 8601 `YYYY-MM-DDTHH:MM[:SS[.fff]]` with `Z` or `±HH[:]MM`
/// (a date alone is midnight UTC), or an integer of Unix seconds. nullopt when unparsable.
std::optional<std::int64_t> parse_event_time(std::string_view text);
/// `YYYY-MM-DDTHH:MMZ`, with `:SS` when the seconds are not zero.
std::string format_event_time(std::int64_t seconds);

struct EventCategory {
  std::string name, column;
  std::vector<double> edges;        ///< empty for a string column
  std::vector<std::string> labels;  ///< code -> label
};

/// The table. Row order is the file's (rows dropped by --skip-invalid removed).
struct EventTable {
  std::vector<format::Double2> points;  ///< x = longitude, y = latitude
  std::vector<std::int64_t> times;      ///< Unix seconds
  std::vector<EventCategory> categories;
  std::vector<std::uint32_t> codes;  ///< category-major: codes[c * rows + r]
  std::string lon_column, lat_column, time_column;
  std::uint64_t rows_skipped = 0;
  std::string first_skipped;  ///< why the first row --skip-invalid dropped was refused
  /// Every category's labels in one string table (index_event_labels fills them).
  std::vector<std::uint64_t> label_offsets;
  std::string label_bytes;

  std::size_t rows() const { return times.size(); }
  std::uint32_t code(std::size_t category, std::size_t row) const {
    return codes[category * rows() + row];
  }
};

/// Fills `label_offsets`/`label_bytes` from the categories' labels (what the blob stores).
void index_event_labels(EventTable& table);

/// Reads a CSV event table from bytes (`path` names it in errors: "path:LINE: column 'time':
/// ..."). Throws ImportError with one line.
EventTable read_event_csv(const std::string& path, std::string_view text,
                          const EventColumns& columns);

}  // namespace kiln
