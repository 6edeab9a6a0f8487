// Manual timing for Google Benchmark runs whose bodies are too long for its own timer loop.
#pragma once

#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>

namespace kiln::bench {

// Times body() once per iteration, reports it as the iteration's time and keeps the fastest
// in `best` (NAN on entry: nothing measured yet).
template <class Body>
void timed(benchmark::State& state, double& best, Body body) {
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    body();
    const double s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    state.SetIterationTime(s);
    best = std::isnan(best) ? s : std::min(best, s);
  }
}

}  // namespace kiln::bench
