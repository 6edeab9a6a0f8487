// `kiln build` around the blob: a depfile naming every file the import read.
#pragma once

#include <string>
#include <vector>

#include "kiln/compiler/build.hpp"

namespace kiln {

struct BuildJob {
  BuildOptions options;
  std::string output;   // the blob, written atomically
  std::string depfile;  // empty: none; else written after the blob, naming `output` as given
};

struct BuildJobReport {
  std::vector<std::string> read_files;  // every file the import read: what the depfile lists
  std::vector<std::string> warnings;    // trouble that did not fail the build, one line each
  std::vector<AccelReport> accels;      // per structure built
};

// Imports, compiles and writes the blob, then the depfile. When
// the build fails nothing is written: the depfile's paths are checked before the blob is
// written. Throws ImportError, DepfileError, std::runtime_error (a write failed).
BuildJobReport run_build_job(const BuildJob& job, const BuildProgress& progress = {});

}  // namespace kiln
