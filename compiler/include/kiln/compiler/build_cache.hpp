// A content-addressed cache of built blobs, in the manner of ccache's direct mode: the files an
// import reads beyond its command-line inputs (an OBJ's .mtl, a glTF's .bin) are only known
// after importing, so a first key over what is known up front leads to a manifest that lists
// them with their hashes; an entry matches when every listed file still hashes the same.
//
// Layout under the cache folder (every file written to a temporary in its own folder and
// renamed into place, so concurrent builds sharing the folder only ever see whole files):
//   CACHEDIR.TAG                 marks the folder as a cache for backup tools
//   manifests/KK/KEY             the entries (newest first) for the direct key KEY
//   blobs/BB/BLOB.kiln           a blob, named by the XXH3-128 of its bytes
// KEY and BLOB are 32 hex digits; KK and BB their first two.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "kiln/compiler/build.hpp"

namespace kiln {

struct Hash128 {
  std::uint64_t high = 0;
  std::uint64_t low = 0;
  friend bool operator==(const Hash128&, const Hash128&) = default;
};

std::string to_hex(const Hash128& hash);  // 32 lower-case hex digits, high half first
std::optional<Hash128> parse_hash128(std::string_view hex);
Hash128 hash_bytes(std::span<const std::byte> bytes);  // XXH3-128, seed 0
// hash_bytes of a regular file's contents, streamed; none when it is not one or cannot be read.
std::optional<Hash128> hash_file(const std::string& path);

// What, besides the inputs and options, decides a blob's bytes: kiln's version, the container
// format's version, the cache layout's revision, Assimp's, Draco's and zstd's versions, and the
// XXH3-128 of the running executable (so a rebuilt kiln, say a builder fix that changes the
// output without a version bump, never reuses another build's entries). One line of text.
// Throws std::runtime_error when the executable cannot be read.
std::string toolchain_fingerprint();

// The direct key: `fingerprint`, the options that shape the output (each structure's name, kind
// and the options its kind declares as entering the output, as canonical text; compression and,
// when on, its level; never the thread counts), and per input in order its path as given (the blob
// records it), its absolute path (companions are found relative to it) and `input_hashes[i]`.
Hash128 direct_key(const BuildOptions& options, std::span<const Hash128> input_hashes,
                   std::string_view fingerprint);

struct CachedFile {
  std::string path;  // absolute, lexically normal (as FileAccesses)
  Hash128 hash;
  friend bool operator==(const CachedFile&, const CachedFile&) = default;
};

// One earlier result: the blob, and every file its import read or looked for in vain.
struct CacheEntry {
  Hash128 blob;
  std::uint64_t blob_size = 0;
  std::vector<CachedFile> read;
  std::vector<std::string> missing;
};

// A manifest as text: a header line, the entries, and a checksum line over the rest, so a
// damaged manifest (one that lost the line naming a companion, say) is never half-trusted.
std::string format_manifest(std::span<const CacheEntry> entries);
// The entries of a manifest; none when it is damaged.
std::vector<CacheEntry> parse_manifest(std::string_view text);

// The entries stored for `key`; none when there are none or the manifest is unreadable.
std::vector<CacheEntry> read_manifest(const std::string& cache_dir, const Hash128& key);

// Whether every file `entry` read still hashes the same (`current_hash` gives a file's hash now,
// none when unreadable) and every file it missed is still absent.
bool entry_matches(const CacheEntry& entry,
                   const std::function<std::optional<Hash128>(const std::string&)>& current_hash);

// Copies the entry's blob to `output` atomically (cloned where the file system can), checking
// the copy's size and hash before renaming it into place. False, `output` untouched, when the
// stored blob is missing or damaged; throws std::runtime_error when `output` cannot be written.
bool restore_blob(const std::string& cache_dir, const CacheEntry& entry, const std::string& output);

// Stores a copy of the file `blob` (the build's output, whose hash and size `entry` holds; a copy
// that differs is not stored) and puts `entry` first in the manifest for `key`, after
// `previous` (what read_manifest gave; entries over the same files are replaced, at most 8
// kept). Throws std::runtime_error when the cache cannot be written or the copy differs.
void store_entry(const std::string& cache_dir, const Hash128& key, const std::string& blob,
                 const CacheEntry& entry, std::span<const CacheEntry> previous);

// Creates the cache folder and its CACHEDIR.TAG if missing. Throws std::runtime_error.
void prepare_cache_dir(const std::string& cache_dir);

}  // namespace kiln
