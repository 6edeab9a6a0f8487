#pragma once

#include <string>

namespace kiln {

// `kiln render`. Options are kept as text and checked by run_render, so every bad value gets
// one line on stderr, exit status 1 and no output file.
struct RenderArgs {
  std::string blob, out, accel;
  std::string mode;  // empty: heatmap with --compare, else shade
  std::string size = "640x400";
  std::string camera;   // empty: frame the scene bounds
  std::string compare;  // comma-separated structure names
  unsigned threads = 0;
  bool json = false;
};
// Returns the exit code.
int run_render(const RenderArgs& args);

}  // namespace kiln
