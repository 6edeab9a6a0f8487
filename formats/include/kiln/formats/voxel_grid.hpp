// What every voxel structure shares: the cubic grid's resolution limits, the Morton order of its
// voxels and the 32-bit octahedral normal attached to a voxel.
#pragma once

#include <cmath>
#include <cstdint>

namespace kiln::format {

inline constexpr std::uint32_t kVoxelMinResolution = 8;
/// The largest grid a voxel format describes: 17 levels, 51-bit Morton codes, coordinates that
/// floats hold exactly (casts work in float grid space). The voxel DAG, built out of core, goes
/// there; the kinds that voxelize the whole grid at once stop at kVoxelInCoreMaxResolution.
inline constexpr std::uint32_t kVoxelMaxResolution = 131072;
/// The largest grid of the structures built in core (ESVO, SSVDAG, the DAG with --solid or
/// --voxel-normals), and of voxelize_surface: their memory follows the surface voxels.
inline constexpr std::uint32_t kVoxelInCoreMaxResolution = 16384;

/// Whether `n` voxels per side is a usable grid: a power of two in [kVoxelMinResolution, max];
/// `max` is the kind's own limit (kVoxelInCoreMaxResolution unless the kind says otherwise).
inline bool is_valid_voxel_resolution(std::uint32_t n,
                                      std::uint32_t max = kVoxelInCoreMaxResolution) {
  return (n & (n - 1)) == 0 && n >= kVoxelMinResolution && n <= max && n <= kVoxelMaxResolution;
}

// Morton code of a voxel: bit 3i holds bit i of x, 3i+1 of y, 3i+2 of z.
inline std::uint64_t spread_bits(std::uint32_t v) {
  std::uint64_t x = v & 0x1FFFFFu;
  x = (x | x << 32) & 0x1F00000000FFFFull;
  x = (x | x << 16) & 0x1F0000FF0000FFull;
  x = (x | x << 8) & 0x100F00F00F00F00Full;
  x = (x | x << 4) & 0x10C30C30C30C30C3ull;
  x = (x | x << 2) & 0x1249249249249249ull;
  return x;
}
inline std::uint64_t morton_code(std::uint32_t x, std::uint32_t y, std::uint32_t z) {
  return spread_bits(x) | spread_bits(y) << 1 | spread_bits(z) << 2;
}
inline std::uint32_t compact_bits(std::uint64_t x) {
  x &= 0x1249249249249249ull;
  x = (x | x >> 2) & 0x10C30C30C30C30C3ull;
  x = (x | x >> 4) & 0x100F00F00F00F00Full;
  x = (x | x >> 8) & 0x1F0000FF0000FFull;
  x = (x | x >> 16) & 0x1F00000000FFFFull;
  x = (x | x >> 32) & 0x1FFFFFull;
  return std::uint32_t(x);
}

// A unit normal in 32 bits: octahedral mapping (Meyer et al. 2010), two signed 16-bit fractions.
inline std::uint32_t encode_octahedral(float x, float y, float z) {
  const float l1 = std::fabs(x) + std::fabs(y) + std::fabs(z);
  if (!(l1 > 0.0f)) return 0;
  float u = x / l1, v = y / l1;
  if (z < 0.0f) {
    const float fu = (1.0f - std::fabs(v)) * (u < 0.0f ? -1.0f : 1.0f);
    const float fv = (1.0f - std::fabs(u)) * (v < 0.0f ? -1.0f : 1.0f);
    u = fu, v = fv;
  }
  const auto q = [](float f) { return std::uint16_t(std::int16_t(std::lround(f * 32767.0f))); };
  return std::uint32_t(q(u)) | std::uint32_t(q(v)) << 16;
}
inline void decode_octahedral(std::uint32_t bits, float n[3]) {
  float u = float(std::int16_t(bits & 0xFFFF)) / 32767.0f;
  float v = float(std::int16_t(bits >> 16)) / 32767.0f;
  const float z = 1.0f - std::fabs(u) - std::fabs(v);
  if (z < 0.0f) {
    const float fu = (1.0f - std::fabs(v)) * (u < 0.0f ? -1.0f : 1.0f);
    const float fv = (1.0f - std::fabs(u)) * (v < 0.0f ? -1.0f : 1.0f);
    u = fu, v = fv;
  }
  const float length = std::sqrt(u * u + v * v + z * z);
  n[0] = u / length, n[1] = v / length, n[2] = z / length;
}

}  // namespace kiln::format
