// The shared worker threads behind parallel_for, fork_join and ForkedTask: every index and task
// runs exactly once, on any thread count (more than the workers too), nested to any depth, from
// several submitting threads at once, and exceptions come back as documented.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdint>
#include <stdexcept>
#include <thread>
#include <vector>

#include <sys/wait.h>
#include <unistd.h>

#include "kiln/runtime/parallel.hpp"

namespace kiln {
namespace {

TEST(Parallel, ForRunsEveryIndexOnceOnAnyThreadCount) {
  for (const unsigned threads : {1u, 2u, 3u, 8u, 64u}) {
    for (const std::size_t count :
         {std::size_t(0), std::size_t(1), std::size_t(7), std::size_t(10000)}) {
      std::vector<std::atomic<int>> hits(count);
      parallel_for(count, threads, [&](std::size_t i) { ++hits[i]; });
      for (std::size_t i = 0; i < count; ++i)
        ASSERT_EQ(hits[i].load(), 1) << "index " << i << " of " << count << ", " << threads;
    }
  }
}

TEST(Parallel, ForRethrowsTheLowestIndexsException) {
  for (const unsigned threads : {1u, 2u, 8u}) {
    try {
      parallel_for(1000, threads, [](std::size_t i) {
        if (i % 97 == 13) throw std::runtime_error(std::to_string(i));
      });
      FAIL() << "no exception";
    } catch (const std::runtime_error& e) {
      EXPECT_STREQ(e.what(), "13") << threads << " threads";
    }
  }
}

// A sum over a binary tree of fork_joins, 2^depth leaves, each forking: nested waits must all
// complete whether a worker or the joiner runs each task.
std::uint64_t tree_sum(std::uint64_t first, unsigned depth) {
  if (depth == 0) return first;
  std::uint64_t left = 0, right = 0;
  fork_join(
      true, [&] { left = tree_sum(first, depth - 1); },
      [&] { right = tree_sum(first + (std::uint64_t(1) << (depth - 1)), depth - 1); });
  return left + right;
}

TEST(Parallel, NestedForksAllComplete) {
  const unsigned depth = 12;
  const std::uint64_t n = std::uint64_t(1) << depth;
  EXPECT_EQ(tree_sum(0, depth), n * (n - 1) / 2);
}

TEST(Parallel, ParallelForInsideForkedTasks) {
  std::vector<std::atomic<int>> hits(64 * 100);
  parallel_for(64, 4, [&](std::size_t t) {
    fork_join(
        true, [&] { parallel_for(50, 3, [&](std::size_t i) { ++hits[t * 100 + i]; }); },
        [&] { parallel_for(50, 3, [&](std::size_t i) { ++hits[t * 100 + 50 + i]; }); });
  });
  for (std::size_t i = 0; i < hits.size(); ++i) ASSERT_EQ(hits[i].load(), 1) << i;
}

TEST(Parallel, ForkJoinRethrowsHeresExceptionFirst) {
  try {
    fork_join(
        true, [] { throw std::runtime_error("here"); }, [] { throw std::runtime_error("forked"); });
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "here");
  }
  try {
    fork_join(
        true, [] {}, [] { throw std::runtime_error("forked"); });
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "forked");
  }
}

TEST(Parallel, ForkedTaskOutlivesAThrowingCaller) {
  // The caller throws while its task may still be running: the task's destructor waits, so the
  // task never touches a dead frame (ASan would see it).
  std::atomic<int> ran{0};
  for (int round = 0; round < 200; ++round) {
    try {
      std::vector<int> local(64, round);
      auto body = [&] {
        int sum = 0;
        for (const int v : local) sum += v;
        ran += sum == 64 * round ? 1 : 1000;
      };
      ForkedTask task(body);
      throw std::runtime_error("caller");
    } catch (const std::runtime_error&) {
    }
  }
  EXPECT_EQ(ran.load(), 200);
}

TEST(Parallel, SeveralSubmittingThreadsAtOnce) {
  // As a server's request threads would: each runs its own parallel loops and forks.
  std::atomic<std::uint64_t> total{0};
  std::vector<std::thread> callers;
  for (int c = 0; c < 4; ++c)
    callers.emplace_back([&] {
      for (int round = 0; round < 20; ++round) {
        std::atomic<std::uint64_t> sum{0};
        parallel_for(1000, 2, [&](std::size_t i) { sum += i; });
        total += sum.load() + tree_sum(0, 6);
      }
    });
  for (auto& t : callers) t.join();
  EXPECT_EQ(total.load(), 4u * 20u * (999u * 1000u / 2u + 64u * 63u / 2u));
}

TEST(Parallel, AForkedChildProcessGetsWorkingThreads) {
  // As Python's multiprocessing does: fork after the workers started. The child has none of them
  // (and maybe a mutex one held): it must still run loops and forks, on threads of its own.
  parallel_for(100, 2, [](std::size_t) {});
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    std::atomic<std::uint64_t> sum{0};
    parallel_for(1000, 2, [&](std::size_t i) { sum += i; });
    const bool ok = sum.load() == 999u * 1000u / 2u && tree_sum(0, 8) == 256u * 255u / 2u;
    _exit(ok ? 0 : 1);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
}

}  // namespace
}  // namespace kiln
