// The event table input in a blob (issue 18): its raw sections and its manifest table.
#pragma once

#include <vector>

#include "kiln/compiler/blob_writer.hpp"
#include "kiln/compiler/event_table.hpp"
#include "manifest_builder.hpp"

namespace flatbuffers {
class FlatBufferBuilder;
}

namespace kiln {

/// Appends the table's columns (borrowing `table`) and records their indices.
void add_event_sections(const EventTable& table, std::vector<SectionPayload>& sections,
                        InputSectionIndices& indices);

/// Writes the manifest's EventTable input table; returns its offset.
std::uint32_t event_table_manifest(flatbuffers::FlatBufferBuilder& fbb, const EventTable& table,
                                   const InputSectionIndices& indices);

}  // namespace kiln
