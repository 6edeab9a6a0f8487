#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <string>

namespace kiln {

// Called after each chunk is written: (bytes written, total bytes).
using WriteProgress = std::function<void(std::size_t, std::size_t)>;

// Writes `bytes` to a temporary file in the target's folder, fsyncs it and renames it over
// `path`, so readers see the old file or the whole new one, never a partial one. On any
// failure the temporary is removed and std::runtime_error names the path.
void write_file_atomically(const std::string& path, std::span<const std::byte> bytes,
                           const WriteProgress& progress = {});

/// A run of a file's bytes starting at `offset`.
struct FilePiece {
  std::uint64_t offset = 0;
  std::span<const std::byte> bytes;
};

// As write_file_atomically, for a file of `size` bytes given as pieces in increasing offset
// order, the gaps between them zeros: a blob goes to disk straight from its sections, never
// concatenated in memory. Throws std::logic_error when pieces overlap or pass `size`.
void write_pieces_atomically(const std::string& path, std::span<const FilePiece> pieces,
                             std::uint64_t size, const WriteProgress& progress = {});

// Copies `source` to `path` as write_file_atomically writes: into a temporary beside `path`,
// sharing the source's extents (FICLONE: instant and no extra space on btrfs or XFS) where the
// file system allows, copying the bytes otherwise. `accept` then sees the finished temporary's
// descriptor (readable, at any offset through pread) and may refuse it: the temporary is removed,
// `path` is untouched and the result is false. Throws std::runtime_error naming the path that
// failed.
bool copy_file_atomically(const std::string& source, const std::string& path,
                          const std::function<bool(int fd)>& accept);

// Makes SIGINT, SIGTERM and SIGHUP remove an in-flight temporary before the process dies.
// (SIGKILL cannot be caught; the output path is untouched then, a stray temporary may remain.)
void install_temp_file_cleanup_on_signals();

}  // namespace kiln
