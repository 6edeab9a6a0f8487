// The manifest's FlatBuffers tables, for code that reads a blob's manifest directly: each
// structure kind's runtime file, and programs that want every recorded field. Blob's own header
// stays free of generated types.
#pragma once

#include <cstring>
#include <vector>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/error.hpp"
#include "kiln/schema/manifest_generated.h"

namespace kiln {

inline const schema::Manifest& manifest_of(const Blob& blob) {
  return *static_cast<const schema::Manifest*>(blob.manifest_root());
}

inline const schema::Structure& structure_table(const Blob& blob, const StructureInfo& info) {
  return *manifest_of(blob).structures()->Get(info.index);
}

/// The description table of structure `info`, of the kind's type `Desc` (checked when the blob
/// was opened: the registry matches each kind to its union member).
/// A manifest vector of 8-byte scalars ([double], [uint64]) copied out with memcpy: the
/// FlatBuffers verifier aligns a vector's length to 4 bytes only, so in forged bytes its
/// elements may sit at 4 mod 8, where reading them in place is undefined.
template <class T>
std::vector<T> copy_vector(const flatbuffers::Vector<T>* v) {
  std::vector<T> out(v != nullptr ? v->size() : 0);
  if (!out.empty()) std::memcpy(out.data(), v->Data(), out.size() * sizeof(T));
  return out;
}

template <class Desc>
const Desc& desc_of(const Blob& blob, const StructureInfo& info) {
  const Desc* desc = structure_table(blob, info).desc_as<Desc>();
  if (desc == nullptr) blob.fail("structure '" + info.name + "' lacks its description");
  return *desc;
}

}  // namespace kiln
