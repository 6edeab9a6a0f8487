#pragma once

#include <cstddef>
#include <functional>

namespace kiln {

// The worker count for a `--threads` value: 0 means every hardware thread.
unsigned resolve_thread_count(unsigned requested);

// Runs body(i) for every i in [0, count) on up to `threads` threads. Each index must write only
// its own output slot, so results never depend on scheduling. If bodies throw, the exception of
// the lowest index is rethrown (the same one whatever the thread count).
void parallel_for(std::size_t count, unsigned threads,
                  const std::function<void(std::size_t)>& body);

}  // namespace kiln
