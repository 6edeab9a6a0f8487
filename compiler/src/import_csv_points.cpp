// A CSV table's coordinate columns into a PointTable2, through CsvReader (RFC 4180). Only the two
// coordinate columns are stored: the query tools read the other columns from the CSV itself.
#include <cmath>
#include <string>
#include <system_error>
#include <vector>

#include "kiln/compiler/csv_reader.hpp"
#include "kiln/compiler/geo_import.hpp"

namespace kiln {
namespace {

// A coordinate field (parse_csv_number), finite.
enum class Parsed { kOk, kNotNumber, kNotFinite };
Parsed parse_coordinate(std::string_view text, double& value) {
  const std::optional<double> number = parse_csv_number(text);
  if (!number) return Parsed::kNotNumber;
  value = *number;
  return std::isfinite(value) ? Parsed::kOk : Parsed::kNotFinite;
}

// Quoted for an error line: at most 40 characters, control characters as '?', so the line
// stays one line.
std::string quoted(std::string_view text) {
  std::string out = "'";
  for (std::size_t i = 0; i < text.size() && i < 40; ++i)
    out += static_cast<unsigned char>(text[i]) < 0x20 ? '?' : text[i];
  if (text.size() > 40) out += "...";
  return out + "'";
}

std::size_t find_column(const CsvReader& csv, std::span<const std::string_view> header,
                        const std::string& name) {
  if (const auto column = csv_column(header, name)) return *column;
  std::string columns;
  for (std::size_t i = 0; i < header.size() && i < 20; ++i)
    columns += (i ? ", " : "") + quoted(header[i]);
  if (header.size() > 20) columns += ", ...";
  throw ImportError(
      csv.where("no column " + quoted(name) + " in the header (columns: " + columns + ")"));
}

// The row's point, or the one-line reason it has none.
std::optional<std::string> read_row(std::span<const std::string_view> fields,
                                    const std::size_t column[2], const std::string* names[2],
                                    format::Double2& point) {
  double xy[2];
  for (int axis = 0; axis < 2; ++axis) {
    const std::string column_text = "column " + quoted(*names[axis]);
    if (column[axis] >= fields.size())
      return column_text + ": missing (the row has " + std::to_string(fields.size()) + " fields)";
    switch (parse_coordinate(fields[column[axis]], xy[axis])) {
      case Parsed::kOk:
        break;
      case Parsed::kNotNumber:
        return column_text + ": " + quoted(fields[column[axis]]) + " is not a number";
      case Parsed::kNotFinite:
        return column_text + ": " + quoted(fields[column[axis]]) + " is not finite";
    }
  }
  point = {xy[0], xy[1]};
  return std::nullopt;
}

}  // namespace

PointTable2 import_csv_points(const std::string& path, std::string_view text,
                              const GeoImportOptions& options) {
  if (options.x_column.empty() || options.y_column.empty())
    throw ImportError(path +
                      ": a CSV input needs --lon-column and --lat-column (or --x-column "
                      "and --y-column) naming its coordinate columns");
  PointTable2 table;
  table.x_column = options.x_column, table.y_column = options.y_column;
  try {
    CsvReader csv(path, text);
    std::vector<std::string_view> fields;
    if (!csv.next(fields)) throw ImportError(path + ": no header row");
    const std::size_t column[2] = {find_column(csv, fields, options.x_column),
                                   find_column(csv, fields, options.y_column)};
    const std::string* names[2] = {&options.x_column, &options.y_column};
    // Row offsets are kept only when a row is dropped (feature_points, geo_layer.hpp).
    std::vector<std::uint64_t> row_points{0};
    while (csv.next(fields)) {
      format::Double2 point;
      if (const auto error = read_row(fields, column, names, point)) {
        if (!options.skip_invalid) throw ImportError(csv.where(*error));
        if (table.rows_skipped++ == 0) table.first_skipped = csv.where(*error);
      } else {
        table.points.push_back(point);
        table.bounds.grow(point);
      }
      row_points.push_back(table.points.size());
    }
    if (table.rows_skipped != 0) table.feature_points = std::move(row_points);
  } catch (const std::bad_alloc&) {
    throw ImportError(path + ": out of memory while reading");
  } catch (const ImportError&) {
    throw;
  } catch (const std::runtime_error& e) {
    throw ImportError(e.what());  // CsvReader's own "path:LINE: what"
  }
  if (table.feature_count() == 0) throw ImportError(path + ": no rows after the header");
  return table;
}

}  // namespace kiln
