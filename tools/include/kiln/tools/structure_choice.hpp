// How the tools pick the structure a command runs on, by capability, through the runtime's
// registry: the one --accel names, else the first in the blob that has the capability.
#pragma once

#include <memory>
#include <string>
#include <string_view>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/capabilities.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/runtime/structure_registry.hpp"

namespace kiln {

/// An opened structure and its name. `view` borrows the Blob it was opened from.
struct ChosenStructure {
  std::string name;
  std::unique_ptr<StructureView> view;
};

/// A capability accessor of StructureView: &StructureView::rays, ::surface, ...
template <class Capability>
using CapabilityOf = const Capability* (StructureView::*)() const;

/// The structure `name` of `blob` (empty: the first structure that has the capability `get`),
/// opened. `ability` says what the capability does, for messages ("trace rays"). Throws
/// BlobError when there is no such structure or it lacks the capability.
template <class Capability>
ChosenStructure choose_structure(const Blob& blob, const std::string& name,
                                 CapabilityOf<Capability> get, std::string_view ability) {
  if (!name.empty()) {
    ChosenStructure chosen{name, open_structure(blob, name)};
    if (((*chosen.view).*get)() == nullptr)
      throw BlobError(blob.name() + ": '" + name + "' does not " + std::string(ability));
    return chosen;
  }
  for (const StructureInfo& info : blob.structures()) {
    ChosenStructure chosen{info.name, open_structure(blob, info.name)};
    if (((*chosen.view).*get)() != nullptr) return chosen;
  }
  throw BlobError(blob.name() + ": holds no structure that can " + std::string(ability));
}

}  // namespace kiln
