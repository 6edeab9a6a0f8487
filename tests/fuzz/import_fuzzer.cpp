// libFuzzer harness for one importer: the bytes are a file of the extension KILN_FUZZ_EXTENSION
// (".obj", ".ply", ".stl", ".gltf", ".glb", ".drc", ".ply.zst"; one target each, see
// CMakeLists.txt). The work per input is in import_exercise.hpp, shared with the regression test.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <span>
#include <string>

#include "import_exercise.hpp"

#ifndef KILN_FUZZ_EXTENSION
#error "KILN_FUZZ_EXTENSION names the importer's file extension"
#endif

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bool verbose = std::getenv("KILN_FUZZ_VERBOSE") != nullptr;
  try {
    const std::string refused = kiln::fuzz::import_and_assemble(
        KILN_FUZZ_EXTENSION, std::as_bytes(std::span<const std::uint8_t>(data, size)));
    if (verbose && !refused.empty()) std::fprintf(stderr, "import_fuzzer: %s\n", refused.c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "import_fuzzer: unexpected exception (not ImportError): %s\n", e.what());
    std::abort();
  }
  return 0;
}
