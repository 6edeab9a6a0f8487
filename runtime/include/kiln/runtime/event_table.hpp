// An event table in a blob (issue 18) as spans over its sections: points, times and label codes
// column by column, and every category's labels. Blob::open checks the section sizes, every code
// against its category's label count, the label offsets and that every time lies in
// [time_min, time_max], so a view may index with them freely.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "kiln/formats/vector.hpp"
#include "kiln/runtime/geo_layer.hpp"

namespace kiln {

/// One categorical dimension of an event table.
struct EventCategoryInfo {
  std::string name, column;
  std::vector<double> edges;  ///< empty for a string column
  std::uint64_t first_label = 0, label_count = 0;
};

struct EventTableView {
  std::span<const format::Double2> points;  ///< x = longitude, y = latitude
  std::span<const std::int64_t> times;      ///< Unix seconds
  std::span<const std::uint32_t> codes;     ///< category-major: [c * rows + r]
  StringTableView labels;                   ///< every category's, first_label onwards
  std::vector<EventCategoryInfo> categories;
  std::int64_t time_min = 0, time_max = 0;
  format::Box2d bounds;
  std::uint64_t rows_skipped = 0;
  std::string lon_column, lat_column, time_column;

  std::size_t rows() const { return times.size(); }
  std::span<const std::uint32_t> category_codes(std::size_t c) const {
    return codes.subspan(c * rows(), rows());
  }
  std::string_view label(std::size_t category, std::uint32_t code) const {
    return labels[categories[category].first_label + code];
  }
  /// The category named `name`, or nullopt.
  std::optional<std::size_t> category(std::string_view name) const;
  /// The code of `label` in `category`, or nullopt.
  std::optional<std::uint32_t> code_of(std::size_t category, std::string_view label) const;
};

}  // namespace kiln
