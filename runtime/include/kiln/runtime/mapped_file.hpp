#pragma once

#include <cstddef>
#include <span>
#include <string>

namespace kiln {

// A whole file mapped read-only. Move-only; unmaps on destruction.
class MappedFile {
 public:
  MappedFile() = default;
  // Throws BlobError naming the path when the file cannot be opened or mapped.
  explicit MappedFile(const std::string& path);
  MappedFile(MappedFile&& other) noexcept;
  MappedFile& operator=(MappedFile&& other) noexcept;
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  ~MappedFile();

  std::span<const std::byte> bytes() const { return {data_, size_}; }

 private:
  void release();
  const std::byte* data_ = nullptr;
  std::size_t size_ = 0;
};

}  // namespace kiln
