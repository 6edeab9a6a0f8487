// SplitMix64 (Steele, Lea & Flood 2014): the seeded generator behind every reproducible ray set
// and generated scene, so they are the same on every machine and standard library (no std
// distributions).
#pragma once

#include <cstdint>

namespace kiln {

/// A 64-bit generator whose stream is a pure function of its seed.
class SplitMix64 {
 public:
  explicit SplitMix64(std::uint64_t seed) : state_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double uniform() { return double(next() >> 11) * 0x1p-53; }  ///< in [0, 1)

 private:
  std::uint64_t state_;
};

}  // namespace kiln
