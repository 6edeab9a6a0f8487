// `kiln build` around the blob: a depfile naming every file the import read, and a
// content-addressed cache of earlier results (build_cache.hpp).
#pragma once

#include <string>
#include <vector>

#include "kiln/compiler/build.hpp"

namespace kiln {

struct BuildJob {
  BuildOptions options;
  std::string output;     // the blob, written atomically
  std::string depfile;    // empty: none; else written after the blob, naming `output` as given
  std::string cache_dir;  // empty: no cache
};

struct BuildJobReport {
  std::vector<std::string> read_files;  // every file the import read: what the depfile lists
  bool cache_hit = false;               // the blob came from the cache; `accels` is empty then
  std::string cache_key;                // hex; empty when no cache was consulted
  std::vector<std::string> warnings;    // trouble that did not fail the build, one line each
  std::vector<AccelReport> accels;      // per structure built
};

// Imports, compiles and writes the blob (or copies it from the cache), then the depfile. When
// the build fails nothing is written: the depfile's paths are checked before the blob is
// written. Throws ImportError, DepfileError, std::runtime_error (a write failed).
BuildJobReport run_build_job(const BuildJob& job, const BuildProgress& progress = {});

}  // namespace kiln
