// `kiln dump` and `kiln verify`, built on the runtime library alone.
#pragma once

#include <ostream>
#include <string>

namespace kiln {

struct DumpOptions {
  bool json = false;
  bool all_meshes = false;  // the human table lists the first 32 meshes unless set
};

// Returns the process exit code; errors go to `err` as one line.
int run_dump(const std::string& path, const DumpOptions& options, std::ostream& out,
             std::ostream& err);
int run_verify(const std::string& path, bool json, std::ostream& out, std::ostream& err);

}  // namespace kiln
