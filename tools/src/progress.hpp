#pragma once

#include <chrono>
#include <cstdint>
#include <string>
#include <string_view>

namespace kiln {

// Progress on stderr for long work, only when stderr is a terminal and the work has run for
// over a second; one line rewritten in place, cleared at the end.
class TerminalProgress {
 public:
  TerminalProgress();
  ~TerminalProgress();
  void update(std::string_view stage, std::uint64_t done, std::uint64_t total);

 private:
  bool enabled_;
  bool drawn_ = false;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
};

}  // namespace kiln
