#include "kiln/compiler/atomic_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <utility>

namespace kiln {

namespace {

// The temporary being written, readable from a signal handler (no allocation there).
char g_pending_temp[4096];
std::atomic<bool> g_has_pending_temp{false};

void on_fatal_signal(int signal_number) {
  if (g_has_pending_temp.load()) ::unlink(g_pending_temp);
  std::signal(signal_number, SIG_DFL);
  std::raise(signal_number);
}

std::runtime_error write_error(const std::string& path, const char* what) {
  return std::runtime_error(path + ": " + what + ": " + std::strerror(errno));
}

class TempFile {
 public:
  explicit TempFile(const std::string& target) {
    const std::filesystem::path target_path(target);
    auto dir = target_path.parent_path();
    if (dir.empty()) dir = ".";
    // Built by appending: GCC 12 warns falsely (-Wrestrict, bug 105329) on "." + string.
    std::string name = ".";
    name += target_path.filename().string();
    name += ".tmp.XXXXXX";
    temp_ = (dir / name).string();
    if (temp_.size() >= sizeof(g_pending_temp))
      throw std::runtime_error(target + ": path too long");
    fd_ = ::mkstemp(temp_.data());
    if (fd_ < 0) throw write_error(target, "cannot create a temporary file beside it");
    std::memcpy(g_pending_temp, temp_.c_str(), temp_.size() + 1);
    g_has_pending_temp = true;
  }
  ~TempFile() {
    if (fd_ >= 0) ::close(fd_);
    if (!committed_) ::unlink(temp_.c_str());
    g_has_pending_temp = false;
  }
  int fd() const { return fd_; }
  void commit(const std::string& target) {
    // mkstemp makes 0600; a blob is an ordinary output file.
    const mode_t mask = ::umask(0);
    ::umask(mask);
    if (::fchmod(fd_, 0666 & ~mask) != 0) throw write_error(target, "chmod failed");
    if (::fsync(fd_) != 0) throw write_error(target, "fsync failed");
    if (::close(std::exchange(fd_, -1)) != 0) throw write_error(target, "close failed");
    if (::rename(temp_.c_str(), target.c_str()) != 0) throw write_error(target, "rename failed");
    committed_ = true;
  }

 private:
  std::string temp_;
  int fd_ = -1;
  bool committed_ = false;
};

}  // namespace

void write_file_atomically(const std::string& path, std::span<const std::byte> bytes,
                           const WriteProgress& progress) {
  TempFile temp(path);
  constexpr std::size_t kChunk = 4u << 20;
  std::size_t written = 0;
  while (written < bytes.size()) {
    const std::size_t n = std::min(kChunk, bytes.size() - written);
    const ssize_t got = ::write(temp.fd(), bytes.data() + written, n);
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) throw write_error(path, "write failed");
    written += std::size_t(got);
    if (progress) progress(written, bytes.size());
  }
  temp.commit(path);
}

void install_temp_file_cleanup_on_signals() {
  for (const int s : {SIGINT, SIGTERM, SIGHUP}) std::signal(s, on_fatal_signal);
}

}  // namespace kiln
