#include "kiln/compiler/build_cache.hpp"

#include <assimp/version.h>
#include <draco/core/draco_version.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>
#include <zstd.h>

#include <cerrno>
#include <charconv>
#include <filesystem>
#include <memory>
#include <new>
#include <stdexcept>

#include "kiln/compiler/file_accesses.hpp"
#include "kiln/formats/container.hpp"
#include "kiln/runtime/atomic_file.hpp"
#include "kiln/runtime/file_descriptor.hpp"

namespace kiln {

namespace {

namespace fs = std::filesystem;

// Bumped whenever what goes into a key or the layout of the cache folder changes: entries of an
// older layout are then never looked up again.
constexpr int kCacheLayoutRevision = 2;
constexpr std::size_t kMaxEntriesPerManifest = 8;
constexpr std::size_t kMaxManifestBytes = 16u << 20;
constexpr std::string_view kManifestHeader = "kiln-build-cache-manifest 1\n";
constexpr std::string_view kCacheDirTag =
    "Signature: 8a477f597d28d172789f06886806bc55\n"
    "# This file marks a kiln build cache (kiln build --cache-dir); see "
    "https://bford.info/cachedir/\n";

// XXH3-128 over typed fields. Each string goes in after its length, so two different field
// sequences never feed the same bytes.
class Hasher {
 public:
  Hasher() : state_(XXH3_createState(), XXH3_freeState) {
    if (!state_) throw std::bad_alloc();
    XXH3_128bits_reset(state_.get());
  }
  void bytes(const void* data, std::size_t size) { XXH3_128bits_update(state_.get(), data, size); }
  void u64(std::uint64_t value) { bytes(&value, sizeof value); }
  void text(std::string_view value) {
    u64(value.size());
    bytes(value.data(), value.size());
  }
  void hash(const Hash128& value) {
    u64(value.high);
    u64(value.low);
  }
  Hash128 digest() const {
    const XXH128_hash_t d = XXH3_128bits_digest(state_.get());
    return {d.high64, d.low64};
  }

 private:
  std::unique_ptr<XXH3_state_t, XXH_errorcode (*)(XXH3_state_t*)> state_;
};

// Streams `fd` from offset 0 into a hash; none on a read error. Counts the bytes into `size`.
std::optional<Hash128> hash_descriptor(int fd, std::uint64_t& size) {
  Hasher hasher;
  std::vector<char> buffer(1u << 20);
  size = 0;
  for (;;) {
    const ssize_t got = ::pread(fd, buffer.data(), buffer.size(), off_t(size));
    if (got < 0 && errno == EINTR) continue;
    if (got < 0) return std::nullopt;
    if (got == 0) break;
    hasher.bytes(buffer.data(), std::size_t(got));
    size += std::uint64_t(got);
  }
  // The raw stream state digests like the one-shot function: hash_bytes gives the same value.
  return hasher.digest();
}

// A structure's name, kind and every option its kind says enters the output, in the kind's
// declaration order, as canonical text (so "1" and "1.0" share a key). Thread counts are never
// options, so they never enter.
void hash_request(Hasher& h, const StructureRequest& request) {
  h.text(request.name);
  h.text(request.kind);
  const StructureBuilder* builder = find_structure_builder(request.kind);
  if (!builder) {
    // "auto" (advise.hpp): its options choose the structure. Any other unknown kind fails the
    // build anyway; nothing is stored under its key.
    h.text("unregistered");
    for (const auto& [key, value] : request.options) {
      h.text(key);
      h.text(value);
    }
    return;
  }
  for (const StructureOption& option : builder->options)
    if (option.enters_output) {
      h.text(option.key);
      h.text(request.text_option(option.key));
    }
}

std::string shard_path(const std::string& cache_dir, std::string_view folder, const Hash128& hash,
                       std::string_view suffix) {
  const std::string hex = to_hex(hash);
  return (fs::path(cache_dir) / folder / hex.substr(0, 2) / (hex + std::string(suffix))).string();
}

std::string manifest_path(const std::string& cache_dir, const Hash128& key) {
  return shard_path(cache_dir, "manifests", key, "");
}

std::string blob_path(const std::string& cache_dir, const Hash128& blob) {
  return shard_path(cache_dir, "blobs", blob, ".kiln");
}

std::span<const std::byte> as_bytes(std::string_view text) {
  return std::as_bytes(std::span<const char>(text.data(), text.size()));
}

// Without it every kiln binary of one version would share a key space: no cache then.
std::string executable_hash() {
  const auto hash = hash_file("/proc/self/exe");
  if (!hash) throw std::runtime_error("cannot read the running executable to key the cache");
  return to_hex(*hash);
}

}  // namespace

std::string to_hex(const Hash128& hash) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string hex(32, '0');
  for (int i = 0; i < 16; ++i) {
    hex[std::size_t(15 - i)] = kDigits[(hash.high >> (4 * i)) & 15];
    hex[std::size_t(31 - i)] = kDigits[(hash.low >> (4 * i)) & 15];
  }
  return hex;
}

std::optional<Hash128> parse_hash128(std::string_view hex) {
  if (hex.size() != 32) return std::nullopt;
  Hash128 hash;
  for (std::size_t half = 0; half < 2; ++half) {
    const char* first = hex.data() + 16 * half;
    std::uint64_t& value = half == 0 ? hash.high : hash.low;
    const auto [end, error] = std::from_chars(first, first + 16, value, 16);
    if (error != std::errc() || end != first + 16) return std::nullopt;
  }
  if (to_hex(hash) != hex) return std::nullopt;  // upper case, signs: not ours
  return hash;
}

Hash128 hash_bytes(std::span<const std::byte> bytes) {
  const XXH128_hash_t d = XXH3_128bits(bytes.data(), bytes.size());
  return {d.high64, d.low64};
}

std::optional<Hash128> hash_file(const std::string& path) {
  // O_NONBLOCK: opening a FIFO must not wait for a writer (it is refused just below).
  const FileDescriptor fd(::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK));
  if (fd.get() < 0) return std::nullopt;
  struct stat info {};
  // Not a FIFO or a device: reading one would consume or never end.
  if (::fstat(fd.get(), &info) != 0 || !S_ISREG(info.st_mode)) return std::nullopt;
  std::uint64_t size = 0;
  return hash_descriptor(fd.get(), size);
}

std::string toolchain_fingerprint() {
  static const std::string fingerprint = [] {
    std::string s = std::string(kToolName) + " " + kToolVersion;
    s += "; format " + std::to_string(format::kVersionMajor) + "." +
         std::to_string(format::kVersionMinor);
    s += "; cache layout " + std::to_string(kCacheLayoutRevision);
    s += "; assimp " + std::to_string(aiGetVersionMajor()) + "." +
         std::to_string(aiGetVersionMinor()) + "." + std::to_string(aiGetVersionPatch()) + "-" +
         std::to_string(aiGetVersionRevision());
    s += "; draco ";
    s += draco::kDracoVersion;
    s += "; zstd ";
    s += ZSTD_versionString();
    s += "; executable " + executable_hash();
    return s;
  }();
  return fingerprint;
}

Hash128 direct_key(const BuildOptions& options, std::span<const Hash128> input_hashes,
                   std::string_view fingerprint) {
  // The limits only refuse inputs: a blob that is written never depends on them.
  const auto& [inputs, structures, compression, threads, limits, events, geo] = options;
  if (input_hashes.size() != inputs.size())
    throw std::invalid_argument("direct_key: one hash per input expected");
  Hasher h;
  h.text("kiln build cache key");
  h.text(fingerprint);
  const auto& [compress, level] = compression;
  h.u64(compress);
  if (compress) h.u64(std::uint64_t(level));  // the level is ignored without compression
  h.u64(structures.size());
  for (const StructureRequest& request : structures) hash_request(h, request);
  if (events.active()) h.text(events.key_text());  // issue 18: how the CSV is read
  // How a 2D input is read changes the blob (names, coordinates, skipped features).
  const auto& [name_property, x_column, y_column, skip_invalid] = geo;
  h.text(name_property);
  h.text(x_column);
  h.text(y_column);
  h.u64(skip_invalid);
  h.u64(inputs.size());
  for (std::size_t i = 0; i < inputs.size(); ++i) {
    h.text(inputs[i]);
    h.text(normalize_path(inputs[i]));
    h.hash(input_hashes[i]);
  }
  return h.digest();
}

std::string format_manifest(std::span<const CacheEntry> entries) {
  auto check = [](const std::string& path) {
    if (path.empty() || path.find_first_of("\n\r") != std::string::npos)
      throw std::runtime_error("cannot record the path '" + path + "' in a cache manifest");
  };
  std::string text(kManifestHeader);
  for (const CacheEntry& entry : entries) {
    text += "entry " + to_hex(entry.blob) + " " + std::to_string(entry.blob_size) + "\n";
    for (const CachedFile& file : entry.read) {
      check(file.path);
      text += "read " + to_hex(file.hash) + " " + file.path + "\n";
    }
    for (const std::string& path : entry.missing) {
      check(path);
      text += "missing " + path + "\n";
    }
  }
  text += "checksum " + to_hex(hash_bytes(as_bytes(text))) + "\n";
  return text;
}

std::vector<CacheEntry> parse_manifest(std::string_view text) {
  if (!text.starts_with(kManifestHeader) || !text.ends_with("\n")) return {};
  const std::size_t last = text.rfind('\n', text.size() - 2);
  if (last == std::string_view::npos) return {};
  const std::string_view body = text.substr(0, last + 1);
  const std::string_view checksum_line = text.substr(last + 1, text.size() - last - 2);
  if (checksum_line != "checksum " + to_hex(hash_bytes(as_bytes(body)))) return {};

  std::vector<CacheEntry> entries;
  for (std::size_t start = kManifestHeader.size(); start < body.size();) {
    const std::size_t end = body.find('\n', start);
    const std::string_view line = body.substr(start, end - start);
    start = end + 1;
    if (line.starts_with("entry ")) {
      const std::string_view rest = line.substr(6);
      const auto blob = parse_hash128(rest.substr(0, 32));
      if (!blob || rest.size() < 34 || rest[32] != ' ') return {};
      CacheEntry entry;
      entry.blob = *blob;
      const auto [end_size, error] =
          std::from_chars(rest.data() + 33, rest.data() + rest.size(), entry.blob_size);
      if (error != std::errc() || end_size != rest.data() + rest.size()) return {};
      entries.push_back(std::move(entry));
    } else if (line.starts_with("read ") && !entries.empty()) {
      const auto hash = parse_hash128(line.substr(5, 32));
      if (!hash || line.size() < 39 || line[37] != ' ') return {};
      entries.back().read.push_back({std::string(line.substr(38)), *hash});
    } else if (line.starts_with("missing ") && !entries.empty() && line.size() > 8) {
      entries.back().missing.emplace_back(line.substr(8));
    } else {
      return {};
    }
  }
  return entries;
}

std::vector<CacheEntry> read_manifest(const std::string& cache_dir, const Hash128& key) {
  const FileDescriptor fd(::open(manifest_path(cache_dir, key).c_str(), O_RDONLY | O_CLOEXEC));
  if (fd.get() < 0) return {};
  std::string text;
  std::vector<char> buffer(1u << 16);
  for (;;) {
    const ssize_t got = ::read(fd.get(), buffer.data(), buffer.size());
    if (got < 0 && errno == EINTR) continue;
    if (got < 0) return {};
    if (got == 0) break;
    text.append(buffer.data(), std::size_t(got));
    if (text.size() > kMaxManifestBytes) return {};
  }
  return parse_manifest(text);
}

bool entry_matches(const CacheEntry& entry,
                   const std::function<std::optional<Hash128>(const std::string&)>& current_hash) {
  for (const CachedFile& file : entry.read)
    if (current_hash(file.path) != file.hash) return false;
  for (const std::string& path : entry.missing) {
    std::error_code ec;
    const bool exists = fs::exists(path, ec);
    if (exists || ec) return false;  // cannot tell: not a match
  }
  return true;
}

bool restore_blob(const std::string& cache_dir, const CacheEntry& entry,
                  const std::string& output) {
  const std::string source = blob_path(cache_dir, entry.blob);
  std::error_code ec;
  if (!fs::is_regular_file(source, ec)) return false;
  // The copy itself is checked, not the stored file: what gets renamed over `output` is what
  // was verified, whatever happens to the cache meanwhile.
  return copy_file_atomically(source, output, [&](int fd) {
    std::uint64_t size = 0;
    const auto hash = hash_descriptor(fd, size);
    return hash && *hash == entry.blob && size == entry.blob_size;
  });
}

void store_entry(const std::string& cache_dir, const Hash128& key, const std::string& blob,
                 const CacheEntry& entry, std::span<const CacheEntry> previous) {
  std::vector<CacheEntry> entries{entry};
  for (const CacheEntry& old : previous)
    if (entries.size() < kMaxEntriesPerManifest &&
        (old.read != entry.read || old.missing != entry.missing))
      entries.push_back(old);
  const std::string text = format_manifest(entries);  // throws on an unrecordable path
  // The blob first: a manifest never names a blob that is not there yet. A concurrent build of
  // the same inputs renames an identical file over it, which readers never notice.
  const std::string stored_blob = blob_path(cache_dir, entry.blob);
  fs::create_directories(fs::path(stored_blob).parent_path());
  const bool same = copy_file_atomically(blob, stored_blob, [&](int fd) {
    std::uint64_t size = 0;
    const auto hash = hash_descriptor(fd, size);
    return hash && *hash == entry.blob && size == entry.blob_size;
  });
  if (!same) throw std::runtime_error(blob + " changed while it was copied into the cache");
  const std::string stored_manifest = manifest_path(cache_dir, key);
  fs::create_directories(fs::path(stored_manifest).parent_path());
  write_file_atomically(stored_manifest, as_bytes(text));
}

void prepare_cache_dir(const std::string& cache_dir) {
  fs::create_directories(cache_dir);
  const std::string tag = (fs::path(cache_dir) / "CACHEDIR.TAG").string();
  std::error_code ec;
  if (fs::exists(tag, ec) || ec) return;
  try {
    write_file_atomically(tag, as_bytes(kCacheDirTag));
  } catch (const std::runtime_error&) {
    // A read-only cache still serves hits; storing will say what is wrong.
  }
}

}  // namespace kiln
