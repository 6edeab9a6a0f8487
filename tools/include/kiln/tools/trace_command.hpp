#pragma once

#include <cstdint>
#include <string>

namespace kiln {

struct TraceArgs {
  std::string blob, rays, out, accel;
  bool any_hit = false;
  unsigned threads = 0;
};
// `kiln trace`: returns the exit code; one-line errors on stderr.
int run_trace(const TraceArgs& args);

struct RaysArgs {
  std::string input;  // a mesh or a .kiln blob
  std::string kind = "primary";
  std::uint64_t count = 100000;
  std::uint64_t seed = 1;
  std::string out;
  unsigned threads = 0;
};
// `kiln rays`: returns the exit code.
int run_rays(const RaysArgs& args);

}  // namespace kiln
