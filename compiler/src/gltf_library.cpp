// The one translation unit that compiles tinygltf (header-only). Images are never decoded: a
// geometry importer installs a loader that skips them (see import_gltf.cpp).
#define TINYGLTF_IMPLEMENTATION
#include <tiny_gltf.h>
