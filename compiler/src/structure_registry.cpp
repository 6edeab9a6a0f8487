// The compiler's one list of structure kinds, and how `--accel KIND[:key=value,...]` becomes a
// StructureRequest. Adding a kind adds one declaration and one entry below.
#include "kiln/compiler/structure_builder.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <stdexcept>

namespace kiln {

extern const StructureBuilder kBvhBuilder, kSbvhBuilder, kKdTreeBuilder, kPointTreeBuilder,
    kVoxelDagBuilder, kEsvoBuilder, kOctreeBuilder, kGridBuilder, kNestedGridBuilder;
extern const StructureBuilder kNanocubeBuilder;      // nanocube_entry.cpp (issue 18)
extern const StructureBuilder kPolygonIndexBuilder;  // polygon_index_entry.cpp
extern const StructureBuilder kQuadtreeBuilder;      // quadtree_entry.cpp
extern const StructureBuilder kSsvdagBuilder;        // ssvdag_entry.cpp (issue 20)

namespace {

const StructureBuilder* const kBuilders[] = {
    &kBvhBuilder,        &kSbvhBuilder,         &kKdTreeBuilder,   &kPointTreeBuilder,
    &kVoxelDagBuilder,   &kEsvoBuilder,         &kOctreeBuilder,   &kGridBuilder,
    &kNestedGridBuilder, &kPolygonIndexBuilder, &kQuadtreeBuilder, &kNanocubeBuilder,
    &kSsvdagBuilder};

std::string join(const std::vector<std::string>& items) {
  std::string text;
  for (const std::string& item : items) text += (text.empty() ? "" : ", ") + item;
  return text;
}

std::string kind_names() {
  std::vector<std::string> names;
  for (const StructureBuilder* builder : kBuilders) names.push_back(builder->kind);
  return join(names);
}

bool is_valid_name(std::string_view name) {
  return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
           c == '.' || c == '-';
  });
}

// "key=value,key=value" -> pairs in order; throws the reason (without the spec) otherwise.
std::vector<std::pair<std::string, std::string>> split_settings(std::string_view text) {
  std::vector<std::pair<std::string, std::string>> settings;
  while (true) {
    const std::size_t comma = text.find(',');
    const std::string_view item = text.substr(0, comma);
    const std::size_t equals = item.find('=');
    if (equals == std::string_view::npos || equals == 0)
      throw std::invalid_argument("'" + std::string(item) + "' is not key=value");
    const std::string key(item.substr(0, equals));
    for (const auto& [seen, value] : settings)
      if (seen == key) throw std::invalid_argument(key + ": given twice");
    settings.emplace_back(key, std::string(item.substr(equals + 1)));
    if (comma == std::string_view::npos) return settings;
    text.remove_prefix(comma + 1);
  }
}

const StructureOption* find_option(const StructureBuilder& builder, std::string_view key) {
  for (const StructureOption& option : builder.options)
    if (option.key == key) return &option;
  return nullptr;
}

// The request's name and its explicitly set options; throws the reason (without the spec).
StructureRequest explicit_settings(const StructureBuilder& builder, std::string_view settings) {
  StructureRequest request{builder.kind, builder.kind, {}};
  if (settings.empty()) return request;
  for (auto& [key, value] : split_settings(settings)) {
    if (key == "name") {
      if (!is_valid_name(value))
        throw std::invalid_argument("name: '" + value + "' is not made of A-Z a-z 0-9 _ . -");
      request.name = value;
      continue;
    }
    const StructureOption* option = find_option(builder, key);
    if (!option) {
      std::vector<std::string> keys{"name"};
      for (const StructureOption& o : builder.options) keys.push_back(o.key);
      throw std::invalid_argument("unknown option '" + key + "' for " + builder.kind +
                                  " (one of: " + join(keys) + ")");
    }
    try {
      request.options[key] = option->parse(value);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(key + ": " + e.what());
    }
  }
  return request;
}

double parse_number(std::string_view text) {
  double value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || error != std::errc() || end != text.data() + text.size() ||
      !std::isfinite(value))
    throw std::invalid_argument("not a finite number");
  return value;
}

std::string canonical(double value) {
  char text[32];
  const auto end = std::to_chars(text, text + sizeof text, value).ptr;
  return std::string(text, end);
}

const std::string& option_text(const StructureRequest& request, const std::string& key) {
  const auto it = request.options.find(key);
  if (it == request.options.end())
    throw std::logic_error(request.kind + " has no option '" + key + "'");
  return it->second;
}

}  // namespace

std::span<const StructureBuilder* const> structure_builders() {
  return kBuilders;
}

const StructureBuilder* find_structure_builder(std::string_view kind) {
  for (const StructureBuilder* builder : kBuilders)
    if (builder->kind == kind) return builder;
  return nullptr;
}

StructureRequest resolve_structure_request(std::string_view spec,
                                           const std::map<std::string, std::string>& flags) {
  const std::string where = "--accel " + std::string(spec);
  const std::size_t colon = spec.find(':');
  const std::string_view kind = spec.substr(0, colon);
  const StructureBuilder* builder = find_structure_builder(kind);
  if (!builder)
    throw std::invalid_argument(where + ": unknown structure kind '" + std::string(kind) +
                                "' (one of: " + kind_names() + ")");
  StructureRequest request;
  try {
    request = explicit_settings(
        *builder, colon == std::string_view::npos ? std::string_view() : spec.substr(colon + 1));
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(where + ": " + e.what());
  }
  for (const StructureOption& option : builder->options) {
    if (request.options.count(option.key)) continue;
    const auto flag = option.flag.empty() ? flags.end() : flags.find(option.flag);
    if (flag == flags.end()) {
      request.options[option.key] = option.default_value;
      continue;
    }
    try {
      request.options[option.key] = option.parse(flag->second);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(option.flag + (option.is_switch ? "" : " " + flag->second) +
                                  ": " + e.what());
    }
  }
  return request;
}

std::uint32_t StructureRequest::uint_option(const std::string& key) const {
  return std::uint32_t(std::stoul(option_text(*this, key)));
}

float StructureRequest::float_option(const std::string& key) const {
  return float(double_option(key));
}

double StructureRequest::double_option(const std::string& key) const {
  return parse_number(option_text(*this, key));
}

bool StructureRequest::switch_option(const std::string& key) const {
  return option_text(*this, key) == "true";
}

const std::string& StructureRequest::text_option(const std::string& key) const {
  return option_text(*this, key);
}

std::function<std::string(std::string_view)> parse_uint_in(std::uint64_t lo, std::uint64_t hi) {
  return [lo, hi](std::string_view text) {
    std::uint64_t value = 0;
    const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (text.empty() || error == std::errc::invalid_argument || end != text.data() + text.size())
      throw std::invalid_argument("not an integer");
    if (error != std::errc() || value < lo || value > hi)
      throw std::invalid_argument("must be in " + std::to_string(lo) + ".." + std::to_string(hi));
    return std::to_string(value);
  };
}

std::function<std::string(std::string_view)> parse_float_in(double lo, double hi) {
  return [lo, hi](std::string_view text) {
    const double value = parse_number(text);
    if (value < lo || value > hi)
      throw std::invalid_argument("must be in " + canonical(lo) + ".." + canonical(hi));
    return canonical(value);
  };
}

std::function<std::string(std::string_view)> parse_one_of(std::vector<std::string> choices) {
  return [choices = std::move(choices)](std::string_view text) {
    for (const std::string& choice : choices)
      if (choice == text) return choice;
    throw std::invalid_argument("must be one of: " + join(choices));
  };
}

std::function<std::string(std::string_view)> parse_switch() {
  return [](std::string_view text) -> std::string {
    if (text == "true" || text == "1") return "true";
    if (text == "false" || text == "0") return "false";
    throw std::invalid_argument("must be true or false");
  };
}

}  // namespace kiln
