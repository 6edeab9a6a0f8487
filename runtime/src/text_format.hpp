// printf-style formatting into a std::string, for the human lines of structure descriptions.
#pragma once

#include <cstdio>
#include <string>

namespace kiln {

/// `format` filled with `args` as snprintf fills it, at most 511 characters.
template <class... Args>
std::string printf_string(const char* format, Args... args) {
  char text[512];
  std::snprintf(text, sizeof(text), format, args...);
  return text;
}

}  // namespace kiln
