// The wide BVH's kernel tables, one per instruction set (runtime/src/bvh_wide_kernel_*.cpp).
// Each returns nullptr for a width it lacks or when the build cannot produce its instructions.
#pragma once

#include <cstdint>

#include "kiln/runtime/bvh_wide.hpp"

namespace kiln::bvh_wide {

const BvhWideKernel* scalar_kernel(std::uint32_t width);
const BvhWideKernel* sse_kernel(std::uint32_t width);
const BvhWideKernel* avx2_kernel(std::uint32_t width);
const BvhWideKernel* avx512_kernel(std::uint32_t width);

}  // namespace kiln::bvh_wide
