#include "fault_support.hpp"

#include <fcntl.h>
#include <grp.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>

namespace kiln::test {

namespace fs = std::filesystem;

void write_grid_ply(const std::string& path, int n, float height) {
  std::ofstream out(path, std::ios::binary);
  const int side = n + 1;
  out << "ply\nformat binary_little_endian 1.0\nelement vertex " << side * side
      << "\nproperty float x\nproperty float y\nproperty float z\nelement face " << 2 * n * n
      << "\nproperty list uchar int vertex_indices\nend_header\n";
  for (int y = 0; y < side; ++y)
    for (int x = 0; x < side; ++x) {
      const float p[3] = {float(x) / float(n), float(y) / float(n),
                          height * std::sin(0.37f * float(x)) * std::cos(0.23f * float(y))};
      out.write(reinterpret_cast<const char*>(p), sizeof p);
    }
  auto face = [&](int a, int b, int c) {
    const std::uint8_t count = 3;
    const std::int32_t ids[3] = {a, b, c};
    out.write(reinterpret_cast<const char*>(&count), 1);
    out.write(reinterpret_cast<const char*>(ids), sizeof ids);
  };
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const int v = y * side + x;
      face(v, v + 1, v + side + 1);
      face(v, v + side + 1, v + side);
    }
  if (!out) throw std::runtime_error(path + ": cannot write the grid");
}

namespace {

// The whole file as text; "" for an empty or missing one (test::read_text passes a null pointer
// to memcpy on an empty file, which UBSan reports).
std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// Only async-signal-safe calls between fork and exec.
[[noreturn]] void exec_kiln(std::vector<char*>& argv, const char* stderr_path,
                            const KilnLimits& limits) {
  const int null_fd = ::open("/dev/null", O_RDWR);
  const int err_fd = ::open(stderr_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (null_fd < 0 || err_fd < 0) ::_exit(126);
  ::dup2(null_fd, 0);
  ::dup2(null_fd, 1);
  ::dup2(err_fd, 2);
  if (limits.max_file_bytes) {
    const rlimit limit{*limits.max_file_bytes, *limits.max_file_bytes};
    if (::setrlimit(RLIMIT_FSIZE, &limit) != 0) ::_exit(126);
  }
  if (limits.unprivileged && ::geteuid() == 0 &&
      (::setgroups(0, nullptr) != 0 || ::setgid(65534) != 0 || ::setuid(65534) != 0))
    ::_exit(126);
  ::execv(argv[0], argv.data());
  ::_exit(127);
}

}  // namespace

pid_t spawn_kiln(const std::vector<std::string>& args, const std::string& stderr_path,
                 const KilnLimits& limits) {
  std::vector<std::string> strings{KILN_CLI};
  strings.insert(strings.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& s : strings) argv.push_back(s.data());
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error(std::string("fork failed: ") + std::strerror(errno));
  if (pid == 0) exec_kiln(argv, stderr_path.c_str(), limits);
  return pid;
}

CommandResult wait_kiln(pid_t pid, const std::string& stderr_path) {
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  CommandResult result;
  if (WIFEXITED(status)) result.exit_code = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) result.signal = WTERMSIG(status);
  result.err = slurp(stderr_path);
  return result;
}

CommandResult run_kiln_args(const std::vector<std::string>& args, const std::string& scratch_dir,
                            const KilnLimits& limits) {
  const std::string err = (fs::path(scratch_dir) / "kiln.stderr").string();
  const CommandResult result = wait_kiln(spawn_kiln(args, err, limits), err);
  fs::remove(err);
  return result;
}

std::vector<std::string> temporaries_in(const std::string& dir) {
  std::vector<std::string> found;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::end(it);
       it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.starts_with(".") && name.find(".tmp.") != std::string::npos)
      found.push_back(it->path().string());
  }
  return found;
}

}  // namespace kiln::test
