#pragma once

#include <limits>
#include <string>

namespace kiln {

struct QueryArgs {
  std::string blob, op, in, out, accel;
  float max_distance = std::numeric_limits<float>::infinity();
  unsigned k = 1;
  float radius = 0;
  unsigned threads = 0;
};
// `kiln query`: returns the exit code; one-line errors on stderr.
int run_query(const QueryArgs& args);

}  // namespace kiln
