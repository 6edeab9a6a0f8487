// Resource bombs: inputs that claim or inflate to absurd sizes are refused early, in one line, with
// memory bounded by the stated limit (ImportLimits), and the limits can be raised.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zstd.h>

#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "import_fixtures.hpp"
#include "kiln/compiler/import.hpp"
#include "test_support.hpp"

namespace kiln {
namespace {

std::span<const std::byte> as_bytes(const std::string& text) {
  return std::as_bytes(std::span<const char>(text));
}

// A streamed zstd frame (no content size, as `cmd | zstd` writes) of `repeats` copies of `chunk`,
// compressed chunk by chunk so the test never holds the inflated bytes.
std::vector<std::byte> streamed_zstd(const std::string& head, const std::string& chunk,
                                     std::uint64_t repeats) {
  std::unique_ptr<ZSTD_CCtx, decltype(&ZSTD_freeCCtx)> cctx(ZSTD_createCCtx(), ZSTD_freeCCtx);
  ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_compressionLevel, 1);
  std::vector<std::byte> out;
  std::vector<std::byte> buffer(ZSTD_CStreamOutSize());
  auto feed = [&](const std::string& text, ZSTD_EndDirective mode) {
    ZSTD_inBuffer in{text.data(), text.size(), 0};
    std::size_t left = 1;
    while (in.pos < in.size || (mode == ZSTD_e_end && left != 0)) {
      ZSTD_outBuffer o{buffer.data(), buffer.size(), 0};
      left = ZSTD_compressStream2(cctx.get(), &o, &in, mode);
      EXPECT_FALSE(ZSTD_isError(left));
      out.insert(out.end(), buffer.begin(), buffer.begin() + std::ptrdiff_t(o.pos));
    }
  };
  feed(head, ZSTD_e_continue);
  std::string block;
  while (block.size() < (1u << 20)) block += chunk;
  const std::uint64_t per_block = block.size() / chunk.size();
  for (std::uint64_t done = 0; done < repeats; done += per_block)
    feed(repeats - done >= per_block ? block : block.substr(0, (repeats - done) * chunk.size()),
         ZSTD_e_continue);
  feed("\n", ZSTD_e_end);
  return out;
}

// Runs `body` in a child process; returns the child's peak resident memory in bytes, or -1 when
// it did not exit with status 0.
template <typename F>
long long child_peak_bytes(F body) {
  const pid_t child = ::fork();
  if (child == 0) ::_exit(body() ? 0 : 1);
  int status = 0;
  rusage usage{};
  ::wait4(child, &status, 0, &usage);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) return -1;
  return static_cast<long long>(usage.ru_maxrss) * 1024;
}

bool refused_with(const std::string& path, std::span<const std::byte> bytes,
                  const ImportLimits& limits, const std::string& needle) {
  try {
    import_bytes(path, bytes, limits, false);
  } catch (const ImportError& e) {
    return std::string(e.what()).find(needle) != std::string::npos;
  }
  return false;
}

TEST(ImportLimits, StreamedZstdBombStopsAtTheLimitWithinItsMemory) {
  // 2 GiB of zeros in a few hundred KB; the limit is 64 MiB.
  const auto bomb = streamed_zstd("", std::string(4096, '\0'), std::uint64_t{1} << 19);
  ASSERT_LT(bomb.size(), std::size_t{1} << 20);
  ImportLimits limits;
  limits.max_inflated_bytes = std::uint64_t{64} << 20;
  const long long peak = child_peak_bytes([&] {
    return refused_with("bomb.obj.zst", bomb, limits,
                        "bomb.obj.zst: inflates to more than 64 MiB (the limit; raise it with "
                        "--max-inflated-size)");
  });
  ASSERT_GT(peak, 0) << "the child was not refused with the expected line";
#if defined(__SANITIZE_ADDRESS__)
  // ASan's shadow memory and its quarantine of freed blocks make resident size meaningless.
  GTEST_SKIP() << "peak memory not checked under AddressSanitizer (refusal checked)";
#else
  // A forked child starts with the parent's resident pages, which grow with the tests run
  // before this one: measure them with a child that does nothing, then allow the 64 MiB limit
  // plus the decoder and slack above that.
  const long long base = child_peak_bytes([] { return true; });
  ASSERT_GT(base, 0);
  EXPECT_LT(peak - base, (std::int64_t{64} << 20) + (std::int64_t{96} << 20))
      << "peak " << peak << ", a child doing nothing " << base;
#endif
}

TEST(ImportLimits, ZstdFrameDeclaringTerabytesIsRefusedBeforeInflating) {
  // A frame header alone: magic, descriptor (8-byte content size, no single segment), window
  // descriptor, then a content size of 2^40 bytes.
  std::vector<std::byte> frame{std::byte{0x28}, std::byte{0xB5}, std::byte{0x2F},
                               std::byte{0xFD}, std::byte{0xC0}, std::byte{0x00}};
  const std::uint64_t terabyte = std::uint64_t{1} << 40;
  for (int i = 0; i < 8; ++i) frame.push_back(std::byte((terabyte >> (8 * i)) & 0xFF));
  test::expect_import_error([&] { import_bytes("huge.ply.zst", frame, {}, false); },
                            "huge.ply.zst: inflates to more than 4 GiB");
}

TEST(ImportLimits, InflateLimitCanBeRaised) {
  const std::string obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  const auto packed = streamed_zstd(obj, "# padding to inflate past the limit\n", 2000);
  ImportLimits tight;
  tight.max_inflated_bytes = 1000;
  test::expect_import_error([&] { import_bytes("t.obj.zst", packed, tight, false); },
                            "inflates to more than 1000 bytes");
  const ImportedFile file = import_bytes("t.obj.zst", packed, {}, false);
  ASSERT_EQ(file.meshes.size(), 1u);
  EXPECT_EQ(file.meshes[0].triangles.size(), 1u);
}

TEST(ImportLimits, TruncatedZstdIsOneLine) {
  const auto packed = streamed_zstd("v 0 0 0\n", "v 1 2 3\n", 100000);
  const std::span<const std::byte> cut(packed.data(), packed.size() / 2);
  test::expect_import_error([&] { import_bytes("cut.obj.zst", cut, {}, false); },
                            "cut.obj.zst: zstd: the file ends inside a frame");
}

TEST(ImportLimits, ObjFaceWithTooManyCornersIsRefusedWithItsLine) {
  // 10^8 corner indices on one face line: 600 MB of text, a 10^8-gon for Assimp to triangulate.
  const auto bomb = streamed_zstd("v 0 0 0\nv 1 0 0\nv 0 1 0\nf", " 1 2 3", 100'000'000 / 3);
  ImportLimits limits;
  limits.max_inflated_bytes = std::uint64_t{1} << 30;
  test::expect_import_error(
      [&] { import_bytes("face.obj.zst", bomb, limits, false); },
      "face.obj.zst:4: a face with 99999999 corners; the limit is 4096 (raise it with "
      "--max-face-vertices)");
}

TEST(ImportLimits, FaceLimitCountsContinuedLinesAndCanBeRaised) {
  std::string obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n# a comment\nf 1 2 \\\n 4 3\n";
  ImportLimits limits;
  limits.max_face_vertices = 3;
  test::expect_import_error([&] { import_bytes("quad.obj", as_bytes(obj), limits, false); },
                            "quad.obj:6: a face with 4 corners; the limit is 3");
  limits.max_face_vertices = 4;
  const ImportedFile file = import_bytes("quad.obj", as_bytes(obj), limits, false);
  ASSERT_EQ(file.meshes.size(), 1u);
  EXPECT_EQ(file.meshes[0].triangles.size(), 2u);
}

TEST(ImportLimits, GltfAccessorClaimingBillionsIsRefused) {
  // One triangle's positions in a 36-byte data URI; the accessor claims 10^9 of them.
  const std::string gltf = R"({"asset":{"version":"2.0"},
    "buffers":[{"byteLength":36,
      "uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}],
    "bufferViews":[{"buffer":0,"byteLength":36}],
    "accessors":[{"bufferView":0,"componentType":5126,"count":1000000000,"type":"VEC3",
                  "min":[0,0,0],"max":[1,1,0]}],
    "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],
    "nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}],"scene":0})";
  test::expect_import_error([&] { import_bytes("/nonexistent/a.gltf", as_bytes(gltf), {}, false); },
                            "1000000000 elements do not fit in the buffer view");
}

}  // namespace
}  // namespace kiln
