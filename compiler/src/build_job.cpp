#include "kiln/compiler/build_job.hpp"

#include <sys/stat.h>

#include <ctime>
#include <filesystem>
#include <map>
#include <optional>

#include "kiln/compiler/build_cache.hpp"
#include "kiln/compiler/depfile.hpp"
#include "kiln/compiler/file_accesses.hpp"
#include "kiln/runtime/atomic_file.hpp"

namespace kiln {

namespace {

// The depfile's text, formatted before anything is written: a path no depfile can hold fails
// the build before the blob exists.
std::string depfile_text(const BuildJob& job, const std::vector<std::string>& read_files) {
  return job.depfile.empty() ? std::string() : format_depfile(job.output, read_files);
}

void write_depfile_text(const BuildJob& job, const std::string& text) {
  if (!job.depfile.empty())
    write_file_atomically(job.depfile, std::as_bytes(std::span<const char>(text)));
}

// What --skip-invalid dropped: counted in the blob, said once on the terminal with the first
// reason, so a silently smaller layer is never a surprise.
void warn_skipped(const Scene& scene, std::vector<std::string>& warnings) {
  const auto warn = [&](std::uint64_t n, const char* what, const std::string& first) {
    if (n != 0)
      warnings.push_back("--skip-invalid dropped " + std::to_string(n) + " " + what +
                         (n == 1 ? "" : "s") + "; the first: " + first);
  };
  if (scene.polygons)
    warn(scene.polygons->features_skipped, "feature", scene.polygons->first_skipped);
  if (scene.points2)  // a GeoJSON point table's rows are features
    warn(scene.points2->rows_skipped, scene.points2->x_column.empty() ? "feature" : "row",
         scene.points2->first_skipped);
  if (scene.events) warn(scene.events->rows_skipped, "row", scene.events->first_skipped);
}

// Imports, compiles and writes the blob straight from its sections (never concatenated in
// memory); returns what the import read.
FileAccesses build_and_write(const BuildJob& job, const BuildProgress& progress,
                             BuildJobReport& report) {
  Scene scene = import_scene(job.options.inputs, job.options.threads, progress, job.options.limits,
                             job.options.geo, job.options.events);
  report.read_files = scene.accessed.read;
  warn_skipped(scene, report.warnings);
  const std::string depfile = depfile_text(job, report.read_files);
  if (progress) progress("compile", 0, 1);
  const CompiledBlob blob = compile_blob_pieces(scene, job.options, &report.accels);
  if (progress) progress("compile", 1, 1);
  write_pieces_atomically(job.output, blob.pieces.pieces, blob.pieces.size,
                          [&](std::size_t done, std::size_t total) {
                            if (progress) progress("write", done, total);
                          });
  write_depfile_text(job, depfile);
  return std::move(scene.accessed);
}

// File timestamps come from the kernel's coarse clock, which lags this one: a file written
// before the build began never looks newer than its start (no false alarm for a file saved just
// before), while a write in the first tick after the start can go unseen (a residual race, as in
// ccache's own check).
timespec precise_now() {
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  return now;
}

bool not_before(const timespec& t, const timespec& start) {
  return t.tv_sec > start.tv_sec || (t.tv_sec == start.tv_sec && t.tv_nsec >= start.tv_nsec);
}

// The first of `paths` modified (or replaced) at or after `start`, if any: its bytes may not be
// the ones the import read, so the result must not be cached under its current hash.
std::optional<std::string> changed_since(const std::vector<std::string>& paths,
                                         const timespec& start) {
  for (const std::string& path : paths) {
    struct stat info {};
    if (::stat(path.c_str(), &info) != 0 || not_before(info.st_mtim, start) ||
        not_before(info.st_ctim, start))
      return path;
  }
  return std::nullopt;
}

// Hashes each file once per build: the inputs were hashed for the key already.
class HashMemo {
 public:
  void remember(const std::string& path, const Hash128& hash) { known_[path] = hash; }
  std::optional<Hash128> operator()(const std::string& path) {
    const auto it = known_.find(path);
    if (it != known_.end()) return it->second;
    const auto hash = hash_file(path);
    known_.emplace(path, hash);
    return hash;
  }

 private:
  std::map<std::string, std::optional<Hash128>> known_;
};

// Restores the output (and depfile) from the first entry of `previous` whose recorded files
// still hash the same; false when none matches, or when the matching one is damaged (a warning
// says so, and the rebuild stores a fresh entry for these files).
bool restore_from_cache(const BuildJob& job, const std::vector<CacheEntry>& previous,
                        HashMemo& memo, BuildJobReport& report) {
  for (const CacheEntry& entry : previous) {
    if (!entry_matches(entry, [&](const std::string& path) { return memo(path); })) continue;
    std::vector<std::string> read_files;
    for (const CachedFile& file : entry.read) read_files.push_back(file.path);
    const std::string depfile = depfile_text(job, read_files);
    std::string trouble = "is missing its blob or it is damaged";
    try {
      if (restore_blob(job.cache_dir, entry, job.output)) {
        write_depfile_text(job, depfile);
        report.cache_hit = true;
        report.read_files = std::move(read_files);
        return true;
      }
    } catch (const std::exception& e) {
      trouble = std::string("is unreadable (") + e.what() + ")";
    }
    report.warnings.push_back("cache entry " + report.cache_key + " " + trouble + "; rebuilding");
    return false;
  }
  return false;
}

// Stores a fresh build under `key`, unless a file it read changed since `start` or cannot be
// hashed (then a warning says why it is not cached).
void store_result(const BuildJob& job, const Hash128& key, const FileAccesses& accessed,
                  const timespec& start, const std::vector<CacheEntry>& previous, HashMemo& memo,
                  BuildJobReport& report) {
  if (const auto changed = changed_since(accessed.read, start)) {
    report.warnings.push_back(*changed + " changed during the build; the result is not cached");
    return;
  }
  // The output just written is what gets cached (hashed here, its copy checked against it).
  std::error_code ec;
  const auto blob_hash = hash_file(job.output);
  const auto blob_size = std::filesystem::file_size(job.output, ec);
  if (!blob_hash || ec) {
    report.warnings.push_back(job.output + " cannot be read back; the result is not cached");
    return;
  }
  CacheEntry entry{*blob_hash, blob_size, {}, accessed.missing};
  for (const std::string& path : accessed.read) {
    const auto hash = memo(path);
    if (!hash) {
      report.warnings.push_back(path + " cannot be read back; the result is not cached");
      return;
    }
    entry.read.push_back({path, *hash});
  }
  try {
    store_entry(job.cache_dir, key, job.output, entry, previous);
  } catch (const std::exception& e) {
    report.warnings.push_back(std::string("result not cached: ") + e.what());
  }
}

BuildJobReport run_cached(const BuildJob& job, const BuildProgress& progress) {
  BuildJobReport report;
  const timespec start = precise_now();
  auto without_cache = [&](std::string warning) {
    if (!warning.empty()) report.warnings.push_back(std::move(warning));
    build_and_write(job, progress, report);
    return report;
  };
  std::string fingerprint;
  try {
    prepare_cache_dir(job.cache_dir);
    fingerprint = toolchain_fingerprint();
  } catch (const std::exception& e) {
    return without_cache("cache " + job.cache_dir + " is unusable (" + e.what() +
                         "); building without it");
  }
  HashMemo memo;
  std::vector<Hash128> input_hashes;
  for (const std::string& input : job.options.inputs) {
    const auto hash = memo(normalize_path(input));
    if (!hash) return without_cache("");  // the import reports the unreadable input
    input_hashes.push_back(*hash);
  }
  const Hash128 key = direct_key(job.options, input_hashes, fingerprint);
  report.cache_key = to_hex(key);
  const std::vector<CacheEntry> previous = read_manifest(job.cache_dir, key);
  if (restore_from_cache(job, previous, memo, report)) return report;
  const FileAccesses accessed = build_and_write(job, progress, report);
  store_result(job, key, accessed, start, previous, memo, report);
  return report;
}

}  // namespace

BuildJobReport run_build_job(const BuildJob& job, const BuildProgress& progress) {
  if (!job.cache_dir.empty()) return run_cached(job, progress);
  BuildJobReport report;
  build_and_write(job, progress, report);
  return report;
}

}  // namespace kiln
