// The `kiln` command line: one subcommand per file (*_command.cpp).
#include <CLI/CLI.hpp>

#include <vector>

#include "commands.hpp"
#include "kiln/compiler/build.hpp"
#include "kiln/runtime/atomic_file.hpp"

int main(int argc, char** argv) {
  using namespace kiln::cli;
  kiln::install_temp_file_cleanup_on_signals();
  CLI::App app{"Kiln: compiles meshes into memory-mappable .kiln blobs of acceleration structures"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("kiln ") + kiln::kToolVersion);
  std::vector<Command> commands = {add_build_command(app),  add_dump_command(app),
                                   add_verify_command(app), add_trace_command(app),
                                   add_rays_command(app),   add_query_command(app),
                                   add_render_command(app), add_advise_command(app)};
#ifdef KILN_HAVE_SERVE
  commands.push_back(add_serve_command(app));  // issue 21 (tools/serve/)
#endif
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  for (const Command& command : commands)
    if (*command.app) return command.run();
  return 2;
}
