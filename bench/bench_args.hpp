// Command-line pieces the benchmark programs share.
#pragma once

#include <fnmatch.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace kiln::bench {

// One scene to import: a file, or [LABEL=]@DIR[/PATTERN] (default *.obj) for every matching
// file in DIR, sorted by name, as one scene.
struct MeshSpec {
  std::string label;
  std::vector<std::string> files;
};

// Prints why and returns nothing when a set matches no file.
inline std::optional<MeshSpec> parse_mesh_spec(const std::string& arg) {
  MeshSpec mesh;
  const std::size_t at = arg.find('@');
  const bool is_set = at != std::string::npos && (at == 0 || arg[at - 1] == '=');
  if (!is_set) {
    mesh.files = {arg};
    mesh.label = std::filesystem::path(arg).filename().string();
    return mesh;
  }
  std::filesystem::path dir = arg.substr(at + 1);
  std::string pattern = "*.obj";
  if (!std::filesystem::is_directory(dir)) {
    pattern = dir.filename().string();
    dir = dir.parent_path();
  }
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator(dir, error)) {
    const std::string name = entry.path().filename().string();
    if (entry.is_regular_file() && fnmatch(pattern.c_str(), name.c_str(), 0) == 0)
      mesh.files.push_back(entry.path().string());
  }
  if (error || mesh.files.empty()) {
    std::fprintf(stderr, "%s: no file matches '%s' in '%s'\n", arg.c_str(), pattern.c_str(),
                 dir.c_str());
    return std::nullopt;
  }
  std::sort(mesh.files.begin(), mesh.files.end());
  mesh.label = at > 0 ? arg.substr(0, at - 1) : dir.filename().string() + "/" + pattern;
  return mesh;
}

// Reads "--NAME=VALUE" into `value`; false when `arg` is not that option. Throws on a bad number.
inline bool parse_number_option(std::string_view arg, std::string_view name, auto& value) {
  const std::string prefix = "--" + std::string(name) + "=";
  if (!arg.starts_with(prefix)) return false;
  value =
      std::remove_reference_t<decltype(value)>(std::stoull(std::string(arg.substr(prefix.size()))));
  return true;
}

// Reads "--NAME=A,B,C" into `values` (replacing them); false when `arg` is not that option.
// Throws on a bad number.
template <typename T>
bool parse_list_option(std::string_view arg, std::string_view name, std::vector<T>& values) {
  const std::string prefix = "--" + std::string(name) + "=";
  if (!arg.starts_with(prefix)) return false;
  const std::string list(arg.substr(prefix.size()));
  values.clear();
  for (std::size_t pos = 0; pos <= list.size();) {
    const std::size_t comma = std::min(list.find(',', pos), list.size());
    values.push_back(T(std::stoull(list.substr(pos, comma - pos))));
    pos = comma + 1;
  }
  return true;
}

}  // namespace kiln::bench
