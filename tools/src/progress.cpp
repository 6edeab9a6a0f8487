#include "progress.hpp"

#include <unistd.h>

#include <cstdio>

namespace kiln {

TerminalProgress::TerminalProgress()
    : enabled_(::isatty(STDERR_FILENO) == 1), start_(std::chrono::steady_clock::now()) {}

TerminalProgress::~TerminalProgress() {
  if (drawn_) std::fprintf(stderr, "\r\033[K");
}

void TerminalProgress::update(std::string_view stage, std::uint64_t done, std::uint64_t total) {
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  if (now - start_ < std::chrono::seconds(1)) return;
  if (drawn_ && now - last_draw_ < std::chrono::milliseconds(100) && done != total) return;
  last_draw_ = now;
  drawn_ = true;
  const double percent = total ? 100.0 * double(done) / double(total) : 100.0;
  std::fprintf(stderr, "\r\033[Kkiln: %.*s %5.1f%%", int(stage.size()), stage.data(), percent);
  std::fflush(stderr);
}

}  // namespace kiln
