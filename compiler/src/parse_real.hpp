// Reals in text meshes, parsed as Assimp 5.2.5's fast_atoreal_move parsed them, so that Kiln's
// own readers (PLY, STL) give the bits the Assimp path gave.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <string_view>

namespace kiln {

// The digits at the front of `text`, consumed: the value of the first `max`, how many those
// were, and how many there were in all.
struct Digits {
  std::uint64_t value = 0;
  std::size_t used = 0, total = 0;
};
inline Digits leading_digits(std::string_view& text, std::size_t max) {
  Digits d;
  for (; !text.empty() && text[0] >= '0' && text[0] <= '9'; text.remove_prefix(1), ++d.total)
    if (d.used < max) d.value = d.value * 10 + std::uint64_t(text[0] - '0'), ++d.used;
  return d;
}

// A real as Assimp's fast_atoreal_move reads it (and still reads OBJ): the integer part, plus at
// most 15 decimals scaled in double and rounded to Real, then times 10^exponent in Real. Not
// always the nearest float, but ASCII PLYs import bit for bit as before, and as the same text in
// an OBJ does.
template <class Real>
std::optional<Real> parse_real(std::string_view text) {
  static constexpr double kScale[16] = {0,    1e-1, 1e-2,  1e-3,  1e-4,  1e-5,  1e-6,  1e-7,
                                        1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 1e-14, 1e-15};
  const bool negative = !text.empty() && text[0] == '-';
  if (!text.empty() && (text[0] == '-' || text[0] == '+')) text.remove_prefix(1);
  if (text == "nan" || text == "NaN" || text == "NAN")
    return std::numeric_limits<Real>::quiet_NaN();
  if (text == "inf" || text == "Inf" || text == "INF" || text == "infinity" || text == "Infinity")
    return negative ? -std::numeric_limits<Real>::infinity()
                    : std::numeric_limits<Real>::infinity();
  const Digits integer = leading_digits(text, 19);  // more would overflow: refused
  if (integer.total > 19) return std::nullopt;
  Real value = Real(integer.value);
  std::size_t digits = integer.total;
  if (!text.empty() && text[0] == '.') {
    text.remove_prefix(1);
    const Digits decimals = leading_digits(text, 15);  // the rest ignored
    value += Real(double(decimals.value) * kScale[decimals.used]);
    digits += decimals.total;
  }
  if (digits == 0) return std::nullopt;
  if (!text.empty() && (text[0] == 'e' || text[0] == 'E')) {
    text.remove_prefix(1);
    const bool negative_exponent = !text.empty() && text[0] == '-';
    if (!text.empty() && (text[0] == '-' || text[0] == '+')) text.remove_prefix(1);
    const Digits exponent = leading_digits(text, 19);
    if (exponent.total == 0 || exponent.total > 19) return std::nullopt;
    const Real e = Real(exponent.value);
    value *= std::pow(Real(10), negative_exponent ? -e : e);
  }
  if (!text.empty()) return std::nullopt;
  return negative ? -value : value;
}

}  // namespace kiln
