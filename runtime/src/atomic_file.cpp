#include "kiln/runtime/atomic_file.hpp"

#include <fcntl.h>
#include <linux/fs.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <utility>
#include <vector>

#include "kiln/runtime/file_descriptor.hpp"

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

// Writes `bytes` whole (in chunks, for progress), retrying interrupted writes.
void write_all(int fd, std::span<const std::byte> bytes, const std::string& path,
               std::uint64_t& written, std::uint64_t total, const WriteProgress& progress) {
  constexpr std::size_t kChunk = 4u << 20;
  for (std::size_t done = 0; done < bytes.size();) {
    const std::size_t n = std::min(kChunk, bytes.size() - done);
    const ssize_t got = ::write(fd, bytes.data() + done, n);
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) throw write_error(path, "write failed");
    done += std::size_t(got);
    written += std::uint64_t(got);
    if (progress) progress(written, total);
  }
}

}  // namespace

void write_file_atomically(const std::string& path, std::span<const std::byte> bytes,
                           const WriteProgress& progress) {
  const FilePiece whole{0, bytes};
  write_pieces_atomically(path, {&whole, 1}, bytes.size(), progress);
}

void write_pieces_atomically(const std::string& path, std::span<const FilePiece> pieces,
                             std::uint64_t size, const WriteProgress& progress) {
  static const std::byte zeros[64 * 1024] = {};
  TempFile temp(path);
  std::uint64_t written = 0;
  auto pad_to = [&](std::uint64_t offset) {
    while (written < offset) {
      const auto n = std::size_t(std::min<std::uint64_t>(sizeof zeros, offset - written));
      write_all(temp.fd(), {zeros, n}, path, written, size, progress);
    }
  };
  for (const FilePiece& piece : pieces) {
    if (piece.offset < written || piece.offset + piece.bytes.size() > size)
      throw std::logic_error(path + ": file pieces overlap or overrun the size");
    pad_to(piece.offset);
    write_all(temp.fd(), piece.bytes, path, written, size, progress);
  }
  pad_to(size);
  temp.commit(path);
}

bool copy_file_atomically(const std::string& source, const std::string& path,
                          const std::function<bool(int fd)>& accept) {
  const FileDescriptor source_fd(::open(source.c_str(), O_RDONLY | O_CLOEXEC));
  const int in = source_fd.get();
  if (in < 0) throw write_error(source, "cannot open");
  TempFile temp(path);
  if (::ioctl(temp.fd(), FICLONE, in) != 0) {
    // No reflink here (another file system, or one without shared extents): copy the bytes.
    std::vector<char> buffer(1u << 20);
    for (;;) {
      const ssize_t got = ::read(in, buffer.data(), buffer.size());
      if (got < 0 && errno == EINTR) continue;
      if (got < 0) throw write_error(source, "read failed");
      if (got == 0) break;
      for (ssize_t done = 0; done < got;) {
        const ssize_t put = ::write(temp.fd(), buffer.data() + done, std::size_t(got - done));
        if (put < 0 && errno == EINTR) continue;
        if (put <= 0) throw write_error(path, "write failed");
        done += put;
      }
    }
  }
  if (accept && !accept(temp.fd())) return false;
  temp.commit(path);
  return true;
}

void install_temp_file_cleanup_on_signals() {
  for (const int s : {SIGINT, SIGTERM, SIGHUP}) std::signal(s, on_fatal_signal);
}

}  // namespace kiln
