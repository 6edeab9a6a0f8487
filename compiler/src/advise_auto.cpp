// `kiln build --accel auto[:for=...,rays=...,name=...]`: the request, and its resolution on the
// scene into the structure advise recommends from deterministic measures only.
#include <stdexcept>

#include "kiln/compiler/advise.hpp"

namespace kiln {

namespace {

// "key=value,..." after "auto:"; throws the reason.
void parse_auto_settings(std::string_view text, StructureRequest& request) {
  while (!text.empty()) {
    const std::size_t comma = text.find(',');
    const std::string_view item = text.substr(0, comma);
    const std::size_t equals = item.find('=');
    if (equals == std::string_view::npos)
      throw std::invalid_argument("'" + std::string(item) + "' is not key=value");
    const std::string key(item.substr(0, equals));
    const std::string value(item.substr(equals + 1));
    if (key == "for")
      request.options[key] = std::string(priority_name(parse_priority(value)));
    else if (key == "rays")
      request.options[key] = std::string(rays_name(parse_rays(value)));
    else if (key == "name" && !value.empty())
      request.name = value;
    else
      throw std::invalid_argument("unknown option '" + key +
                                  "' for auto (one of: for, rays, name)");
    if (comma == std::string_view::npos) break;
    text.remove_prefix(comma + 1);
  }
}

}  // namespace

bool is_auto_spec(std::string_view spec) {
  return spec.substr(0, spec.find(':')) == kAutoKind;
}

StructureRequest resolve_auto_request(std::string_view spec) {
  StructureRequest request;
  request.kind = std::string(kAutoKind);
  request.options = {{"for", "trace"}, {"rays", "both"}};
  const std::size_t colon = spec.find(':');
  try {
    if (colon != std::string_view::npos) parse_auto_settings(spec.substr(colon + 1), request);
    if (request.options["for"] == "build")
      throw std::invalid_argument(
          "for=build is not deterministic (build times differ run to run); run kiln advise --for "
          "build and name the structure");
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("--accel " + std::string(spec) + ": " + e.what());
  }
  return request;
}

std::vector<AutoChoice> resolve_auto_requests(const Scene& scene,
                                              std::vector<StructureRequest>& requests,
                                              unsigned threads) {
  std::vector<AutoChoice> choices;
  for (std::size_t i = 0; i < requests.size(); ++i) {
    if (requests[i].kind != kAutoKind) continue;
    if (scene.triangles.empty())
      throw std::invalid_argument("--accel auto: the input has no triangles to trace rays on");
    AdviseOptions options;
    options.priority = parse_priority(requests[i].text_option("for"));
    options.rays = parse_rays(requests[i].text_option("rays"));
    options.threads = threads;
    options.repetitions = 0;  // deterministic columns only: the blob must not depend on the run
    AutoChoice choice{i, {}, advise(scene, options)};
    choice.spec = choice.advice.rows[choice.advice.recommendation.row].spec;
    StructureRequest chosen = resolve_structure_request(choice.spec, {});
    if (!requests[i].name.empty()) chosen.name = requests[i].name;
    requests[i] = std::move(chosen);
    choices.push_back(std::move(choice));
  }
  return choices;
}

}  // namespace kiln
