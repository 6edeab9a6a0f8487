#pragma once

#include <cstddef>
#include <exception>
#include <functional>
#include <thread>

namespace kiln {

// The worker count for a `--threads` value: 0 means every hardware thread.
unsigned resolve_thread_count(unsigned requested);

// Runs body(i) for every i in [0, count) on up to `threads` threads. Each index must write only
// its own output slot, so results never depend on scheduling. If bodies throw, the exception of
// the lowest index is rethrown (the same one whatever the thread count).
void parallel_for(std::size_t count, unsigned threads,
                  const std::function<void(std::size_t)>& body);

// parallel_for in tasks of `batch` consecutive indices: amortises scheduling for cheap bodies
// (one ray, one query) and keeps each index's output slot fixed.
template <class Body>
void parallel_for_batched(std::size_t count, std::size_t batch, unsigned threads, Body body) {
  parallel_for((count + batch - 1) / batch, threads, [&](std::size_t b) {
    const std::size_t end = count < (b + 1) * batch ? count : (b + 1) * batch;
    for (std::size_t i = b * batch; i < end; ++i) body(i);
  });
}

/// How deep recursive builders fork: enough subtrees for `threads` workers (0 = all cores) with
/// one level of slack for uneven halves; 0 (never fork) for one thread.
unsigned fork_depth(unsigned threads);

/// The one fork-join of the recursive builders: when `fork`, runs `forked` on a new thread while
/// `here` runs on this one, joins, and rethrows `here`'s exception, else `forked`'s; otherwise
/// runs `here` then `forked`. Each must write only its own output, so the result never depends
/// on whether it forked (blobs are byte-identical on any thread count).
template <class Here, class Forked>
void fork_join(bool fork, Here&& here, Forked&& forked) {
  if (!fork) {
    here();
    forked();
    return;
  }
  std::exception_ptr forked_error;
  std::jthread worker([&] {
    try {
      forked();
    } catch (...) {
      forked_error = std::current_exception();
    }
  });
  here();  // if it throws, the jthread joins on unwinding
  worker.join();
  if (forked_error) std::rethrow_exception(forked_error);
}

}  // namespace kiln
