#include "kiln/runtime/parallel.hpp"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#if defined(__unix__)
#include <pthread.h>
#endif

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace kiln {

namespace {

void cpu_relax() {
#if defined(__x86_64__) || defined(__i386__)
  _mm_pause();
#endif
}

// How long an idle thread polls for work before it sleeps: long enough to bridge the gaps
// between a build's parallel phases (a sleeping thread took up to 80 us to wake on this VM),
// short enough that an idle process soon stops using a core.
constexpr auto kSpin = std::chrono::microseconds(200);

}  // namespace

/// The shared worker threads and their queue. A task is queued exactly while nobody has claimed
/// it; claims happen under the mutex, so a joiner that finds its task still queued removes it
/// and runs it itself, and no thread ever holds a pointer to a task that has finished.
class TaskPool {
 public:
  static TaskPool& get();

  void push(ForkedTask* t) {
    {
      const std::lock_guard lock(mutex_);
      start_workers();
      queue_.push_back(t);
      queued_.store(queue_.size(), std::memory_order_release);
    }
    if (sleepers_.load(std::memory_order_acquire) > 0) wake_.notify_all();
  }

  /// Removes `t` from the queue if it is still there.
  bool unqueue(ForkedTask* t) {
    const std::lock_guard lock(mutex_);
    const auto it = std::find(queue_.rbegin(), queue_.rend(), t);  // usually the newest
    if (it == queue_.rend()) return false;
    queue_.erase(std::next(it).base());
    queued_.store(queue_.size(), std::memory_order_release);
    return true;
  }

  /// Claims the oldest queued task (the largest, in a fork tree), or none.
  ForkedTask* pop() {
    if (queued_.load(std::memory_order_acquire) == 0) return nullptr;
    const std::lock_guard lock(mutex_);
    if (queue_.empty()) return nullptr;
    ForkedTask* t = queue_.front();
    queue_.pop_front();
    queued_.store(queue_.size(), std::memory_order_release);
    return t;
  }

  // After a task's `done` store (sequentially consistent, as are the sleepers' count and a
  // joiner's check of `done`: either this sees the sleeper, or the sleeper sees `done`).
  void finished() {
    if (sleepers_.load() == 0) return;
    const std::lock_guard lock(mutex_);  // orders the task's `done` before a sleeper's check
    wake_.notify_all();
  }

  /// Runs queued tasks until `ready()`: polls for kSpin, then sleeps until a task is queued or
  /// one finishes.
  template <class Ready>
  void work_until(const Ready& ready) {
    auto idle_since = std::chrono::steady_clock::now();
    for (unsigned polls = 0; !ready();) {
      if (ForkedTask* t = pop()) {
        t->run();
        idle_since = std::chrono::steady_clock::now(), polls = 0;
        continue;
      }
      cpu_relax();
      if (++polls % 64 != 0 || std::chrono::steady_clock::now() - idle_since < kSpin) continue;
      std::unique_lock lock(mutex_);
      sleepers_.fetch_add(1);  // sequentially consistent with the `done` store, see finished()
      wake_.wait(lock, [&] { return ready() || !queue_.empty(); });
      sleepers_.fetch_sub(1);
      idle_since = std::chrono::steady_clock::now(), polls = 0;
    }
  }

 private:
  // Under the mutex, on the first task: one worker per hardware thread but the submitter's.
  void start_workers() {
    if (started_) return;
    started_ = true;
    const unsigned n = resolve_thread_count(0);
    for (unsigned i = 1; i < n; ++i)
      workers_.emplace_back([this] { work_until([] { return false; }); });
  }

  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<ForkedTask*> queue_;
  std::atomic<std::size_t> queued_{0};
  std::atomic<int> sleepers_{0};
  bool started_ = false;
  std::vector<std::jthread> workers_;
};

// The pool lives as long as the process (its workers are never joined: they sleep when idle, and
// no task can be running at exit, since every task is joined before its caller returns). A child
// made by fork() has none of the parent's threads and maybe a mutex locked by one of them: it
// gets a fresh pool, and the parent's is left as it is.
namespace {
std::atomic<TaskPool*> g_pool{nullptr};
}  // namespace

TaskPool& TaskPool::get() {
  if (TaskPool* pool = g_pool.load(std::memory_order_acquire)) return *pool;
  static std::once_flag once;
  std::call_once(once, [] {
#if defined(__unix__)
    pthread_atfork(nullptr, nullptr, [] { g_pool.store(new TaskPool); });
#endif
    g_pool.store(new TaskPool);
  });
  return *g_pool.load(std::memory_order_acquire);
}

void ForkedTask::submit() {
  TaskPool::get().push(this);
}

void ForkedTask::run() noexcept {
  try {
    call_(body_);
  } catch (...) {
    error_ = std::current_exception();
  }
  done_.store(true);
  TaskPool::get().finished();
}

void ForkedTask::wait() {
  TaskPool& pool = TaskPool::get();
  if (pool.unqueue(this)) return run();
  pool.work_until([this] { return done_.load(); });
}

unsigned resolve_thread_count(unsigned requested) {
  if (requested != 0) return requested;
  return std::max(1u, std::thread::hardware_concurrency());
}

unsigned fork_depth(unsigned threads) {
  const unsigned workers = resolve_thread_count(threads);
  if (workers <= 1) return 0;
  unsigned depth = 0;
  while ((1u << depth) < workers) ++depth;
  return depth + 1;
}

void parallel_for(std::size_t count, unsigned threads,
                  const std::function<void(std::size_t)>& body) {
  std::vector<std::exception_ptr> errors(count);
  std::atomic<std::size_t> next{0};
  auto worker = [&] {
    for (std::size_t i = next++; i < count; i = next++) {
      try {
        body(i);
      } catch (...) {
        errors[i] = std::current_exception();
      }
    }
  };
  const std::size_t helpers = std::min<std::size_t>(resolve_thread_count(threads), count);
  if (helpers <= 1) {
    worker();
  } else {
    std::vector<std::unique_ptr<ForkedTask>> tasks;
    for (std::size_t t = 1; t < helpers; ++t) tasks.push_back(std::make_unique<ForkedTask>(worker));
    worker();
    for (auto& t : tasks) t->join();  // one still queued runs here and finds no index left
  }
  for (const auto& error : errors)
    if (error) std::rethrow_exception(error);
}

}  // namespace kiln
