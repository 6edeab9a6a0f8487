// Make-syntax dependency files, as `gcc -MD` writes them: what Make, Ninja (`depfile =`) and
// CMake's add_custom_command(DEPFILE) read to rebuild a blob when any file its import read changes.
#pragma once

#include <span>
#include <stdexcept>
#include <string>
#include <string_view>

namespace kiln {

// A path that no depfile can hold: Make and Ninja have no escape for a newline, and read a name
// ending in a backslash differently.
class DepfileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// `path` escaped for a depfile: a space or tab becomes "\ " (backslashes right before it are
// doubled, as Make expects), '#' becomes "\#", '$' becomes "$$". Colons stay as they are, as
// gcc writes them. Throws DepfileError for an empty path or one Make and Ninja cannot read back.
std::string escape_depfile_path(std::string_view path);

// "TARGET:", then each dependency on a line of its own, every line but the last ending in a
// backslash continuation (" \"), two spaces before each dependency, a newline at the end; so
// `out.kiln` reading two files gives the three lines "out.kiln: \", "  /abs/m.obj \" and
// "  /abs/m.mtl". `target` is written exactly as given: the build system matches it against
// its output.
// Throws DepfileError (escape_depfile_path).
std::string format_depfile(std::string_view target, std::span<const std::string> dependencies);

}  // namespace kiln
