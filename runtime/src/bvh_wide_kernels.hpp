// The wide BVH's kernel tables, one per instruction set (runtime/src/bvh_wide_kernel_*.cpp).
// Each returns nullptr for a width it lacks or when the build cannot produce its instructions.
#pragma once

#include <cstdint>

#include "kiln/runtime/bvh_wide.hpp"

namespace kiln::bvh_wide {

const BvhWideKernel* scalar_kernel(std::uint32_t width, bool quantized);
const BvhWideKernel* sse_kernel(std::uint32_t width, bool quantized);
const BvhWideKernel* avx2_kernel(std::uint32_t width, bool quantized);
const BvhWideKernel* avx512_kernel(std::uint32_t width, bool quantized);

}  // namespace kiln::bvh_wide
