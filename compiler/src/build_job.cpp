#include "kiln/compiler/build_job.hpp"

#include "kiln/compiler/atomic_file.hpp"
#include "kiln/compiler/depfile.hpp"

namespace kiln {

BuildJobReport run_build_job(const BuildJob& job, const BuildProgress& progress) {
  BuildJobReport report;
  const Scene scene = import_scene(job.options.inputs, job.options.threads, progress);
  report.read_files = scene.accessed.read;
  // Formatted before anything is written: a path no depfile can hold fails the build cleanly.
  const std::string depfile_text =
      job.depfile.empty() ? std::string() : format_depfile(job.output, report.read_files);
  if (progress) progress("compile", 0, 1);
  const std::vector<std::byte> blob = compile_blob(scene, job.options, &report.accels);
  if (progress) progress("compile", 1, 1);
  write_file_atomically(job.output, blob, [&](std::size_t done, std::size_t total) {
    if (progress) progress("write", done, total);
  });
  if (!job.depfile.empty())
    write_file_atomically(job.depfile, std::as_bytes(std::span<const char>(depfile_text)));
  return report;
}

}  // namespace kiln
