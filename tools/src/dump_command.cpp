// `kiln dump` and `kiln verify`: the command lines of the inspector (inspect.cpp).
#include <iostream>
#include <memory>
#include <string>

#include "commands.hpp"
#include "kiln/tools/inspect.hpp"

namespace kiln::cli {

Command add_dump_command(CLI::App& app) {
  struct Args {
    std::string blob;
    DumpOptions options;
  };
  auto args = std::make_shared<Args>();
  auto* command = app.add_subcommand("dump", "Print a blob's header, sections and manifest");
  command->add_option("blob", args->blob, "The .kiln file")->required();
  command->add_flag("--json", args->options.json, "Machine-readable JSON on stdout");
  command->add_flag("--all-meshes", args->options.all_meshes, "List every mesh in the table");
  return {command, [args] { return run_dump(args->blob, args->options, std::cout, std::cerr); }};
}

Command add_verify_command(CLI::App& app) {
  struct Args {
    std::string blob;
    bool json = false;
  };
  auto args = std::make_shared<Args>();
  auto* command = app.add_subcommand("verify", "Check a blob completely, every checksum included");
  command->add_option("blob", args->blob, "The .kiln file")->required();
  command->add_flag("--json", args->json, "Machine-readable JSON on stdout");
  return {command, [args] { return run_verify(args->blob, args->json, std::cout, std::cerr); }};
}

}  // namespace kiln::cli
