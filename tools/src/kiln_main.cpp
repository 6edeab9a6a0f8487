// The `kiln` command line: build, dump, verify.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "kiln/compiler/atomic_file.hpp"
#include "kiln/compiler/build.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/compiler/parallel.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/tools/inspect.hpp"
#include "progress.hpp"

namespace {

constexpr unsigned kMaxThreads = 1024;

struct BuildArgs {
  std::vector<std::string> inputs;
  std::string output;
  bool compress = false;
  int level = 9;
  unsigned threads = 0;
  bool stats = false;
};

int run_build(const BuildArgs& args) {
  namespace fs = std::filesystem;
  std::error_code ec;
  for (const auto& input : args.inputs)
    if (fs::exists(args.output, ec) && fs::equivalent(input, args.output, ec)) {
      std::cerr << "kiln build: output " << args.output << " is also an input\n";
      return 2;
    }
  kiln::BuildOptions options;
  options.inputs = args.inputs;
  options.compression = {args.compress, args.level};
  options.threads = args.threads;
  const auto start = std::chrono::steady_clock::now();
  try {
    kiln::TerminalProgress progress;
    kiln::build_blob_file(options, args.output,
                          [&](std::string_view stage, std::uint64_t done, std::uint64_t total) {
                            progress.update(stage, done, total);
                          });
  } catch (const kiln::ImportError& e) {
    std::cerr << "kiln build: " << e.what() << "\n";
    return 1;
  } catch (const std::bad_alloc&) {
    std::cerr << "kiln build: out of memory\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "kiln build: " << e.what() << "\n";
    return 1;
  }
  if (args.stats) {
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const auto blob = kiln::Blob::open_file(args.output);
    const auto* scene = blob.manifest().scene();
    std::fprintf(
        stderr,
        "kiln build: %s: %llu triangles, %llu vertices, %llu bytes in %.3f s (%u threads)\n",
        args.output.c_str(), (unsigned long long)scene->triangle_count(),
        (unsigned long long)scene->vertex_count(), (unsigned long long)blob.header().file_size,
        seconds, kiln::resolve_thread_count(args.threads));
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  kiln::install_temp_file_cleanup_on_signals();
  CLI::App app{"Kiln: compiles meshes into memory-mappable .kiln blobs of acceleration structures"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("kiln ") + kiln::kToolVersion);

  BuildArgs build;
  auto* build_cmd = app.add_subcommand("build", "Import meshes and write a .kiln blob");
  build_cmd
      ->add_option("inputs", build.inputs,
                   "Mesh files (OBJ, PLY, STL, FBX, DAE, 3DS, OFF, 3MF, glTF/GLB, DRC; "
                   "a .zst suffix is inflated first)")
      ->required();
  build_cmd->add_option("-o,--output", build.output, "The blob to write (atomically)")->required();
  build_cmd->add_flag("--compress", build.compress,
                      "zstd-compress each section (trades zero-copy mapping for size)");
  build_cmd->add_option("--compression-level", build.level, "zstd level")
      ->check(CLI::Range(1, 22))
      ->capture_default_str();
  build_cmd
      ->add_option("--threads", build.threads,
                   "Worker threads (0 = all cores); never changes the output")
      ->check(CLI::Range(0u, kMaxThreads))
      ->capture_default_str();
  build_cmd->add_flag("--stats", build.stats, "Print build time and sizes to stderr");

  std::string dump_path;
  kiln::DumpOptions dump_options;
  auto* dump_cmd = app.add_subcommand("dump", "Print a blob's header, sections and manifest");
  dump_cmd->add_option("blob", dump_path, "The .kiln file")->required();
  dump_cmd->add_flag("--json", dump_options.json, "Machine-readable JSON on stdout");
  dump_cmd->add_flag("--all-meshes", dump_options.all_meshes, "List every mesh in the table");

  std::string verify_path;
  bool verify_json = false;
  auto* verify_cmd =
      app.add_subcommand("verify", "Check a blob completely, every checksum included");
  verify_cmd->add_option("blob", verify_path, "The .kiln file")->required();
  verify_cmd->add_flag("--json", verify_json, "Machine-readable JSON on stdout");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  if (*build_cmd) return run_build(build);
  if (*dump_cmd) return kiln::run_dump(dump_path, dump_options, std::cout, std::cerr);
  if (*verify_cmd) return kiln::run_verify(verify_path, verify_json, std::cout, std::cerr);
  return 2;
}
