// Same inputs and options give byte-identical blobs, whatever the thread count.
#include "kiln/compiler/build.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

std::vector<std::byte> build_bytes(const std::vector<std::string>& inputs, unsigned threads,
                                   bool compress) {
  BuildOptions options;
  options.inputs = inputs;
  options.threads = threads;
  options.compression.enabled = compress;
  return compile_blob(import_scene(inputs, threads), options);
}

TEST(Determinism, ByteIdenticalAcrossRunsAndThreadCounts) {
  KILN_REQUIRE_CORPUS();
  const std::vector<std::string> inputs = {
      test::mesh_path("stanford/stanford-bunny.obj.zst"),
      test::mesh_path("gltf/2CylinderEngine-glTF-Draco/2CylinderEngine.gltf"),
      test::mesh_path("classic/teapot.obj"), test::mesh_path("stanford/Lucy100k.ply")};
  for (const bool compress : {false, true}) {
    SCOPED_TRACE(compress ? "zstd" : "raw");
    const auto one = build_bytes(inputs, 1, compress);
    const auto again = build_bytes(inputs, 1, compress);
    const auto two = build_bytes(inputs, 2, compress);
    const auto eight = build_bytes(inputs, 8, compress);
    EXPECT_EQ(one, again);
    EXPECT_EQ(one, two);
    EXPECT_EQ(one, eight);
    EXPECT_EQ(test::open_and_verify(one), "");
  }
}

// The builders spawn threads for large subtrees; the tree must not depend on it.
TEST(Determinism, BvhBuildsAreByteIdenticalAcrossThreadCounts) {
  KILN_REQUIRE_CORPUS();
  const std::vector<std::string> inputs = {test::mesh_path("stanford/Lucy100k.ply"),
                                           test::mesh_path("stanford/stanford-bunny.obj.zst")};
  const Scene scene = import_scene(inputs, 2);
  auto blob = [&](unsigned threads) {
    BuildOptions options;
    options.inputs = inputs;
    options.threads = threads;
    options.structures = {resolve_structure_request("bvh:builder=sweep", {}),
                          resolve_structure_request("sbvh", {})};
    return compile_blob(scene, options);
  };
  const auto one = blob(1);
  EXPECT_EQ(one, blob(2));
  EXPECT_EQ(one, blob(8));
  EXPECT_EQ(test::open_and_verify(one), "");
}

}  // namespace
}  // namespace kiln
