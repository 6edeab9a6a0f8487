// RFC 4180 CSV records over bytes in memory: comma-separated, fields optionally in double quotes
// (a quote inside doubled), CRLF or LF line ends, a header row first. Used by the 2D point
// tables and the event tables; the query tools read their CSV inputs with it too.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace kiln {

/// Reads one record at a time. Unquoted fields are views into the input; a quoted field is
/// unescaped into storage the reader owns, valid until the next call to next().
class CsvReader {
 public:
  /// `path` names the file in errors ("path:LINE: what").
  CsvReader(std::string path, std::string_view text);

  /// The next record's fields, or false at the end of the input. A record ending without a
  /// newline at the end of the input is a record; an empty line is skipped. Throws
  /// std::runtime_error ("path:LINE: ...") on a quote that never closes or text after a
  /// closing quote.
  bool next(std::vector<std::string_view>& fields);

  /// The 1-based line where the record last returned by next() starts.
  std::uint64_t line() const { return record_line_; }
  const std::string& path() const { return path_; }

  /// "path:LINE: what", for errors about the last record.
  std::string where(std::string_view what) const;

 private:
  std::string path_;
  std::string_view text_;
  std::size_t pos_ = 0;
  std::uint64_t line_ = 1, record_line_ = 0;
  // The current record's quoted fields, unescaped into one buffer; views are made once the
  // record is complete, so growing the buffer never invalidates one.
  std::string scratch_;
  struct Span {
    bool scratch;
    std::size_t begin, size;
  };
  std::vector<Span> spans_;
};

/// The index of the header field named `name`, or nullopt.
std::optional<std::size_t> csv_column(std::span<const std::string_view> header,
                                      std::string_view name);

/// A number field as CSV tables write them: surrounding spaces and tabs ignored, an optional
/// leading '+', then what std::from_chars reads as a whole (decimal or scientific, "inf", "nan").
/// A value too small for a double reads as a zero, one too large as an infinity, both with their
/// sign. nullopt for anything else; callers that need a finite value check it themselves.
std::optional<double> parse_csv_number(std::string_view field);

}  // namespace kiln
