// `kiln-dump`: the inspector as a stand-alone binary linked against the runtime alone, proving
// a consumer can read blobs without the compiler or its importers.
#include <CLI/CLI.hpp>

#include <iostream>

#include "kiln/tools/inspect.hpp"

int main(int argc, char** argv) {
  CLI::App app{"kiln-dump: print or verify a .kiln blob (runtime library only)"};
  std::string path;
  kiln::DumpOptions options;
  bool verify = false;
  app.add_option("blob", path, "The .kiln file")->required();
  app.add_flag("--json", options.json, "Machine-readable JSON on stdout");
  app.add_flag("--all-meshes", options.all_meshes, "List every mesh in the table");
  app.add_flag("--verify", verify, "Verify every checksum instead of dumping");
  CLI11_PARSE(app, argc, argv);
  if (verify) return kiln::run_verify(path, options.json, std::cout, std::cerr);
  return kiln::run_dump(path, options, std::cout, std::cerr);
}
