// The blob's structures: each manifest entry matched to its registered kind and checked by it
// (O(1) per structure), then found by name.
#include <string>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/manifest.hpp"
#include "kiln/runtime/structure_registry.hpp"

namespace kiln {

void Blob::validate_structures() {
  const auto* list = manifest_of(*this).structures();
  const std::uint32_t count = list ? list->size() : 0;
  for (std::uint32_t i = 0; i < count; ++i) {
    const schema::Structure& table = *list->Get(i);
    StructureInfo info{i, table.name()->str(), table.kind()->str(), {}};
    const auto where = "structure '" + info.name + "'";
    if (structure(info.name) != nullptr)
      fail_section(0, "two structures named '" + info.name + "'");
    const StructureKind* kind = find_structure_kind(info.kind);
    if (kind == nullptr)
      fail_section(0, "unknown structure kind '" + info.kind + "' (written by a newer kiln?)");
    if (table.desc_type() == schema::StructureDesc::NONE)
      fail_section(0, where + " has no description");
    if (std::uint8_t(table.desc_type()) != kind->desc_type)
      fail_section(0, where + " of kind '" + info.kind + "' holds another kind's description (" +
                          schema::EnumNameStructureDesc(table.desc_type()) + ")");
    if (!input_provides(input_.kind, kind->consumes))
      fail_section(0, where + " of kind '" + info.kind + "' needs a " +
                          std::string(input_kind_name(kind->consumes)) +
                          "; the blob's input is a " + std::string(input_kind_name(input_.kind)));
    if (table.sections() != nullptr)
      for (const std::uint32_t index : *table.sections()) {
        if (index == 0 || index >= sections_.size())
          fail_section(0, where + " names section " + std::to_string(index) + ", out of range");
        info.sections.push_back(index);
      }
    structures_.push_back(std::move(info));
    kind->check(*this, structures_.back());
  }
}

const StructureInfo* Blob::structure(std::string_view name) const {
  for (const StructureInfo& info : structures_)
    if (info.name == name) return &info;
  return nullptr;
}

}  // namespace kiln
