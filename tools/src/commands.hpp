// The `kiln` subcommands: each adds itself to the command line and returns how to run it.
#pragma once

#include <CLI/CLI.hpp>

#include <functional>
#include <string>

namespace kiln::cli {

/// Larger --threads values are refused: they are typos.
inline constexpr unsigned kMaxThreads = 1024;

/// A subcommand and its runner (which returns the exit code), valid once the line is parsed.
struct Command {
  CLI::App* app = nullptr;
  std::function<int()> run;
};

Command add_build_command(CLI::App& app);
Command add_dump_command(CLI::App& app);
Command add_verify_command(CLI::App& app);
Command add_trace_command(CLI::App& app);
Command add_rays_command(CLI::App& app);
Command add_query_command(CLI::App& app);
Command add_render_command(CLI::App& app);
Command add_advise_command(CLI::App& app);
Command add_serve_command(CLI::App& app);  ///< only with cpp-httplib (tools/serve/)

/// "--threads": worker threads, 0 = all cores; `help` says what they never change.
inline CLI::Option* add_threads_option(CLI::App* command, unsigned& threads,
                                       const std::string& help = "Worker threads (0 = all cores)") {
  return command->add_option("--threads", threads, help)->check(CLI::Range(0u, kMaxThreads));
}

}  // namespace kiln::cli
