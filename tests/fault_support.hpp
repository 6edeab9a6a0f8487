// Helpers for the fault tests (build_kill_test, build_write_errors_test, blob_replace_test): a
// generated mesh big enough that a build takes a while, and the kiln CLI run as a child process
// that a test can kill, limit (RLIMIT_FSIZE) or run without root's privileges.
#pragma once

#include <sys/types.h>

#include <optional>
#include <string>
#include <vector>

#include "test_support.hpp"

namespace kiln::test {

// A binary little-endian PLY of an n x n grid of quads (2 n^2 triangles), its height a wave
// scaled by `height`: two different heights give two different blobs.
void write_grid_ply(const std::string& path, int n, float height);

struct KilnLimits {
  std::optional<unsigned long> max_file_bytes;  // RLIMIT_FSIZE; SIGXFSZ left at its default
  bool unprivileged = false;                    // as root: run as nobody (uid/gid 65534)
};

// Starts `kiln ARGS...` (no shell between: the pid is kiln's own) with stdin and stdout on
// /dev/null and stderr into `stderr_path`. Throws std::runtime_error when fork fails.
pid_t spawn_kiln(const std::vector<std::string>& args, const std::string& stderr_path,
                 const KilnLimits& limits = {});
// Waits for a spawned kiln: its exit code or the signal that ended it, and its stderr.
CommandResult wait_kiln(pid_t pid, const std::string& stderr_path);
// spawn_kiln then wait_kiln, stderr into a file of `scratch_dir`.
CommandResult run_kiln_args(const std::vector<std::string>& args, const std::string& scratch_dir,
                            const KilnLimits& limits = {});

// The names in `dir` that look like an atomic writer's temporary (".NAME.tmp.XXXXXX"),
// searched recursively.
std::vector<std::string> temporaries_in(const std::string& dir);

}  // namespace kiln::test
