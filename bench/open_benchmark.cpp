// How long opening a blob takes: mmap + the O(sections) validation, the cost a renderer pays at
// load time. Usage: kiln_bench_open BLOB [google-benchmark flags]
#include <benchmark/benchmark.h>

#include <cstdio>
#include <string>

#include "kiln/runtime/blob.hpp"

namespace {

std::string g_blob_path;

void BM_OpenFile(benchmark::State& state) {
  for (auto _ : state) {
    const kiln::Blob blob = kiln::Blob::open_file(g_blob_path);
    benchmark::DoNotOptimize(blob.triangles().data());
  }
  const kiln::Blob blob = kiln::Blob::open_file(g_blob_path);
  state.counters["triangles"] = double(blob.triangles().size());
}
BENCHMARK(BM_OpenFile)->Unit(benchmark::kMicrosecond);

void BM_Verify(benchmark::State& state) {
  const kiln::Blob blob = kiln::Blob::open_file(g_blob_path);
  for (auto _ : state) blob.verify();
  state.SetBytesProcessed(std::int64_t(state.iterations()) * std::int64_t(blob.header().file_size));
}
BENCHMARK(BM_Verify)->Unit(benchmark::kMillisecond);

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (argc < 2) {
    std::fprintf(stderr, "usage: kiln_bench_open BLOB [benchmark flags]\n");
    return 2;
  }
  g_blob_path = argv[1];
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
