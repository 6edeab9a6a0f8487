// What one acceleration structure contributes to a blob: its sections (bytes it owns), its
// manifest table, and a line for `kiln build --stats`. Each structure has its own file making
// one of these, so compile_blob and the manifest builder know nothing of any layout.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "kiln/compiler/blob_writer.hpp"
#include "kiln/compiler/build.hpp"
#include "kiln/schema/manifest_generated.h"

namespace kiln {

struct AccelEntry {
  std::vector<SectionPayload> sections;  // borrow from `storage`
  std::shared_ptr<const void> storage;
  // The Acceleration table, given the blob's indices of `sections` (in the same order).
  std::function<flatbuffers::Offset<schema::Acceleration>(flatbuffers::FlatBufferBuilder&,
                                                          std::span<const std::uint32_t>)>
      describe;
  std::string summary;  // statistics for --stats, one line, no timing
};

template <class T>
SectionPayload raw_section(std::uint32_t kind, const std::vector<T>& values) {
  return {kind,          std::uint16_t(format::SectionFlag::kRequired), sizeof(T),
          values.size(), std::as_bytes(std::span<const T>(values)),     true};
}

AccelEntry make_bvh_entry(const Scene& scene, const AccelRequest& request, unsigned threads);
AccelEntry make_kdtree_entry(const Scene& scene, const AccelRequest& request, unsigned threads);
AccelEntry make_voxel_dag_entry(const Scene& scene, const AccelRequest& request, unsigned threads);
AccelEntry make_esvo_entry(const Scene& scene, const AccelRequest& request, unsigned threads);
AccelEntry make_point_tree_entry(const Scene& scene, const AccelRequest& request, unsigned threads);

}  // namespace kiln
