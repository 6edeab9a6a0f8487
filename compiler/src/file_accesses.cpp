#include "kiln/compiler/file_accesses.hpp"

#include <algorithm>
#include <filesystem>

namespace kiln {

namespace {

void sort_unique(std::vector<std::string>& paths) {
  std::sort(paths.begin(), paths.end());
  paths.erase(std::unique(paths.begin(), paths.end()), paths.end());
}

}  // namespace

std::string normalize_path(const std::string& path) {
  std::error_code ec;
  const auto absolute = std::filesystem::absolute(path, ec);
  return ec ? path : absolute.lexically_normal().string();
}

void normalize_accesses(FileAccesses& accesses) {
  for (auto* list : {&accesses.read, &accesses.missing}) {
    for (auto& path : *list) path = normalize_path(path);
    sort_unique(*list);
  }
  std::erase_if(accesses.missing, [&](const std::string& path) {
    return std::binary_search(accesses.read.begin(), accesses.read.end(), path);
  });
}

}  // namespace kiln
