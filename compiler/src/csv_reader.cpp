#include "kiln/compiler/csv_reader.hpp"

#include <charconv>
#include <limits>
#include <stdexcept>

namespace kiln {

CsvReader::CsvReader(std::string path, std::string_view text)
    : path_(std::move(path)), text_(text) {
  // A UTF-8 byte order mark is not part of the first column's name.
  if (text_.substr(0, 3) == "\xEF\xBB\xBF") pos_ = 3;
}

std::string CsvReader::where(std::string_view what) const {
  return path_ + ":" + std::to_string(record_line_) + ": " + std::string(what);
}

bool CsvReader::next(std::vector<std::string_view>& fields) {
  fields.clear();
  spans_.clear();
  scratch_.clear();
  // Empty lines between records are skipped.
  while (pos_ < text_.size() && (text_[pos_] == '\n' || text_[pos_] == '\r')) {
    if (text_[pos_] == '\n') ++line_;
    ++pos_;
  }
  if (pos_ >= text_.size()) return false;
  record_line_ = line_;
  for (;;) {
    if (pos_ < text_.size() && text_[pos_] == '"') {
      // A quoted field: up to the closing quote; "" is one quote; newlines are kept.
      const std::size_t begin = scratch_.size();
      for (++pos_;; ++pos_) {
        if (pos_ >= text_.size()) throw std::runtime_error(where("a quoted field never closes"));
        const char c = text_[pos_];
        if (c == '"') {
          if (pos_ + 1 < text_.size() && text_[pos_ + 1] == '"') {
            scratch_ += '"', ++pos_;
            continue;
          }
          ++pos_;
          break;
        }
        if (c == '\n') ++line_;
        scratch_ += c;
      }
      spans_.push_back({true, begin, scratch_.size() - begin});
      if (pos_ < text_.size() && text_[pos_] != ',' && text_[pos_] != '\n' && text_[pos_] != '\r')
        throw std::runtime_error(where("text after the closing quote of a field"));
    } else {
      const std::size_t begin = pos_;
      while (pos_ < text_.size() && text_[pos_] != ',' && text_[pos_] != '\n' &&
             text_[pos_] != '\r')
        ++pos_;
      spans_.push_back({false, begin, pos_ - begin});
    }
    if (pos_ < text_.size() && text_[pos_] == ',') {
      ++pos_;
      continue;
    }
    // End of the record: CRLF, LF, a lone CR, or the end of the input.
    if (pos_ < text_.size() && text_[pos_] == '\r') ++pos_;
    if (pos_ < text_.size() && text_[pos_] == '\n') ++pos_, ++line_;
    break;
  }
  fields.reserve(spans_.size());
  for (const Span& s : spans_)
    fields.push_back(s.scratch ? std::string_view(scratch_).substr(s.begin, s.size)
                               : text_.substr(s.begin, s.size));
  return true;
}

std::optional<std::size_t> csv_column(std::span<const std::string_view> header,
                                      std::string_view name) {
  for (std::size_t i = 0; i < header.size(); ++i)
    if (header[i] == name) return i;
  return std::nullopt;
}

std::optional<double> parse_csv_number(std::string_view text) {
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
  while (!text.empty() && (text.back() == ' ' || text.back() == '\t')) text.remove_suffix(1);
  if (text.size() > 1 && text[0] == '+' && text[1] != '-') text.remove_prefix(1);
  if (text.empty()) return std::nullopt;
  double value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (end != text.data() + text.size()) return std::nullopt;
  if (ec == std::errc::result_out_of_range) {
    // from_chars leaves the value alone: a negative exponent underflowed, anything else overflowed.
    const bool negative = text[0] == '-';
    const std::size_t e = text.find_first_of("eE");
    const bool underflow = e != std::string_view::npos && e + 1 < text.size() && text[e + 1] == '-';
    const double magnitude = underflow ? 0.0 : std::numeric_limits<double>::infinity();
    return negative ? -magnitude : magnitude;
  }
  if (ec != std::errc()) return std::nullopt;
  return value;
}

}  // namespace kiln
