#include "kiln/compiler/depfile.hpp"

namespace kiln {

std::string escape_depfile_path(std::string_view path) {
  if (path.empty()) throw DepfileError("an empty path cannot be written in a depfile");
  if (path.find_first_of("\n\r") != std::string_view::npos || path.back() == '\\')
    throw DepfileError(std::string(path) +
                       ": cannot be written in a depfile (a newline, or a trailing backslash)");
  std::string out;
  out.reserve(path.size() + 8);
  std::size_t backslashes = 0;  // the run of backslashes just copied
  for (const char c : path) {
    switch (c) {
      case ' ':
      case '\t':
        // Make reads 2N+1 backslashes before a blank as N backslashes and a blank in the name.
        out.append(backslashes, '\\');
        out += '\\';
        break;
      case '#':
        out += '\\';
        break;
      case '$':
        out += '$';
        break;
      default:
        break;
    }
    out += c;
    backslashes = c == '\\' ? backslashes + 1 : 0;
  }
  return out;
}

std::string format_depfile(std::string_view target, std::span<const std::string> dependencies) {
  std::string text = escape_depfile_path(target);
  text += ':';
  for (const std::string& dependency : dependencies) {
    text += " \\\n  ";
    text += escape_depfile_path(dependency);
  }
  text += '\n';
  return text;
}

}  // namespace kiln
