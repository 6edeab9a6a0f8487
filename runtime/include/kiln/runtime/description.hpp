// A structure's description for `kiln dump`: human lines, JSON fields and tables, made by its
// kind from the manifest, so the dump prints any structure without naming it.
#pragma once

#include <cstdint>
#include <string>
#include <type_traits>
#include <utility>
#include <variant>
#include <vector>

namespace kiln {

using DescValue = std::variant<bool, std::uint64_t, double, std::string>;

/// A table of per-level (or per-anything) rows, for JSON: an array of objects keyed by
/// `columns`. The human dump prints `lines` only; a kind puts its tables there in its own format.
struct DescTable {
  std::string key;
  std::vector<std::string> columns;
  std::vector<std::vector<DescValue>> rows;
};

struct Description {
  std::vector<std::string> lines;                         ///< human summary, unindented
  std::vector<std::pair<std::string, DescValue>> fields;  ///< JSON members, in order
  std::vector<DescTable> tables;

  template <class T>
  Description& field(std::string key, T value) {
    if constexpr (std::is_same_v<T, bool> || std::is_same_v<T, double> ||
                  std::is_same_v<T, std::string>)
      fields.emplace_back(std::move(key), DescValue(std::move(value)));
    else if constexpr (std::is_floating_point_v<T>)
      fields.emplace_back(std::move(key), DescValue(double(value)));
    else if constexpr (std::is_convertible_v<T, std::string>)
      fields.emplace_back(std::move(key), DescValue(std::string(value)));
    else
      fields.emplace_back(std::move(key), DescValue(std::uint64_t(value)));
    return *this;
  }
};

}  // namespace kiln
