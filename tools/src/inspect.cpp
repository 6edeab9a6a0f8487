// `kiln dump` and `kiln verify` on the runtime library alone; the per-structure parts of the
// dump come from each kind's description in the runtime's registry.
#include "kiln/tools/inspect.hpp"

#include <cinttypes>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

#include "dump_writers.hpp"
#include "kiln/formats/section_kinds.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/structure_registry.hpp"

namespace kiln {

namespace dump {

std::string hex64(std::uint64_t value) {
  char text[20];
  std::snprintf(text, sizeof(text), "%016" PRIx64, value);
  return text;
}

const char* codec_name(std::uint8_t codec) {
  switch (format::Codec(codec)) {
    case format::Codec::kNone:
      return "none";
    case format::Codec::kZstd:
      return "zstd";
  }
  return "?";
}

bool is_required(const format::SectionEntry& section) {
  return (section.flags & std::uint16_t(format::SectionFlag::kRequired)) != 0;
}

Description describe(const Blob& blob, const StructureInfo& info) {
  const StructureKind* kind = find_structure_kind(info.kind);
  return kind != nullptr ? kind->describe(blob, info) : Description{};
}

}  // namespace dump

int run_dump(const std::string& path, const DumpOptions& options, std::ostream& out,
             std::ostream& err) {
  std::string error;
  const auto blob = Blob::try_open_file(path, error);
  if (!blob) {
    err << "kiln dump: " << error << "\n";
    return 1;
  }
  try {
    if (options.json)
      dump::write_json(*blob, out);
    else
      dump::write_human(*blob, options, out);
  } catch (const BlobError& e) {
    err << "kiln dump: " << e.what() << "\n";
    return 1;
  }
  return 0;
}

int run_verify(const std::string& path, bool json, std::ostream& out, std::ostream& err) {
  std::string error;
  auto blob = Blob::try_open_file(path, error);
  if (blob) {
    try {
      blob->verify();
    } catch (const BlobError& e) {
      error = e.what();
    }
  }
  if (json) {
    nlohmann::ordered_json j = {{"file", path}, {"ok", error.empty()}};
    if (!error.empty()) j["error"] = error;
    out << j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
  } else if (error.empty()) {
    out << "ok: " << path << " (" << blob->sections().size() << " sections, "
        << blob->header().file_size << " bytes, all checksums match)\n";
  }
  if (!error.empty()) {
    err << "kiln verify: " << error << "\n";
    return 1;
  }
  return 0;
}

}  // namespace kiln
