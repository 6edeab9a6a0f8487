// The files an import touched: what a depfile lists and what the build cache must re-check.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace kiln {

// After normalize_accesses, every path is absolute and lexically normal (symlinks are not
// resolved: a build system names files the way the user does), and each list is sorted and
// holds no duplicates.
struct FileAccesses {
  std::vector<std::string> read;  // opened for reading, the input itself included
  // Companions an importer looked for and did not find (an OBJ's absent .mtl, a glTF buffer
  // searched beside the file before the working directory): one appearing later can change
  // the output, so the build cache must see them still absent.
  std::vector<std::string> missing;
};

// `path` absolute (against the current directory) and lexically normal: the form of every path
// in FileAccesses. Unchanged when the current directory is gone.
std::string normalize_path(const std::string& path);

// Makes `accesses` absolute (against the current directory, as the importer's fopen saw them),
// lexically normal, sorted and unique; a path both read and missing (probed before it was
// created, or under two spellings) counts as read.
void normalize_accesses(FileAccesses& accesses);

}  // namespace kiln
