// The two forms of `kiln dump` (dump_json.cpp, dump_text.cpp) and what they share.
#pragma once

#include <cstdint>
#include <ostream>
#include <string>
#include <vector>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/description.hpp"
#include "kiln/tools/inspect.hpp"

namespace kiln::dump {

void write_json(const Blob& blob, std::ostream& out);
void write_human(const Blob& blob, const DumpOptions& options, std::ostream& out);

/// 16 lowercase hex digits.
std::string hex64(std::uint64_t value);
/// "none", "zstd" or "?".
const char* codec_name(std::uint8_t codec);
/// Whether a section is flagged required.
bool is_required(const format::SectionEntry& section);
/// The structure's description by its kind in the runtime's registry.
Description describe(const Blob& blob, const StructureInfo& info);
/// What each `kiln build --accel auto` recorded (advise_dump.cpp); empty without one.
std::vector<Description> describe_advice(const Blob& blob);

}  // namespace kiln::dump
