// The blobs `kiln serve` maps: each opened once, read-only, named by its file name without
// `.kiln`, with every structure's view opened once (views validate their arrays at open, so
// requests never repeat that walk). Requests name blobs; no request path reaches the file system.
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/capabilities.hpp"

namespace kiln::serve {

/// One served blob: its name, the mapped blob and its structures' views (in blob order).
struct ServedBlob {
  std::string name;
  std::unique_ptr<Blob> blob;  // views borrow it: it never moves
  std::vector<std::pair<std::string, std::unique_ptr<StructureView>>> structures;
  nlohmann::json info;  ///< what GET /api/blobs says about it

  /// The structure `name` (empty: the first that answers `op`), or nullptr.
  const StructureView* structure(std::string_view name, std::string_view op) const;
};

/// The served blobs, opened from the command line's paths.
class Catalog {
 public:
  /// Opens every path (std::runtime_error with one line on a bad blob or a repeated name).
  explicit Catalog(const std::vector<std::string>& paths);
  /// The blob called `name`; an empty name is the only blob when there is one. nullptr if none.
  const ServedBlob* find(std::string_view name) const;
  const std::vector<ServedBlob>& blobs() const { return blobs_; }
  /// GET /api/blobs: {"blobs": [{name, input, input stats, structures: [{name, kind, ...}]}]}.
  nlohmann::json describe() const;

 private:
  std::vector<ServedBlob> blobs_;
};

/// The name a blob is served under: the file name without its directory and `.kiln`.
std::string blob_name(const std::string& path);

}  // namespace kiln::serve
