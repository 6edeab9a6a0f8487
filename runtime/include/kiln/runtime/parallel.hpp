#pragma once

#include <atomic>
#include <cstddef>
#include <exception>
#include <functional>

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

/// Work handed to the process's shared worker threads (one per hardware thread but the caller's,
/// started on first use and kept: a new thread per fork took 30 us to create and up to 80 us more
/// to start running on this VM, a cost each fork of a 25 ms build paid on its critical path).
/// Constructing one queues `body`; join() returns once it has run, on a worker or, if none took
/// it yet, right here, so every task finishes even with no worker free. A joiner whose task runs
/// elsewhere runs other queued tasks meanwhile. `body` must outlive the task; the destructor
/// joins one not joined yet (unwinding) and drops its exception.
class ForkedTask {
 public:
  template <class Body>
  explicit ForkedTask(Body& body)
      : call_([](void* b) { (*static_cast<Body*>(b))(); }), body_(&body) {
    submit();
  }
  ForkedTask(const ForkedTask&) = delete;
  ForkedTask& operator=(const ForkedTask&) = delete;
  ~ForkedTask() {
    if (!joined_) wait();
  }
  /// Waits until the task has run; rethrows its exception.
  void join() {
    joined_ = true;
    wait();
    if (error_) std::rethrow_exception(error_);
  }

 private:
  friend class TaskPool;
  void submit();
  void wait();
  void run() noexcept;  // on whichever thread claimed it

  void (*call_)(void*);
  void* body_;
  std::exception_ptr error_;
  std::atomic<bool> done_{false};
  bool joined_ = false;
};

/// The one fork-join of the recursive builders: when `fork`, hands `forked` to a worker thread
/// while `here` runs on this one, joins, and rethrows `here`'s exception, else `forked`'s;
/// otherwise runs `here` then `forked`. Each must write only its own output, so the result never
/// depends on whether it forked (blobs are byte-identical on any thread count).
template <class Here, class Forked>
void fork_join(bool fork, Here&& here, Forked&& forked) {
  if (!fork) {
    here();
    forked();
    return;
  }
  ForkedTask task(forked);
  here();  // if it throws, the task joins on unwinding
  task.join();
}

}  // namespace kiln
