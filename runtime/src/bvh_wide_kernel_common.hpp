// What every wide-BVH kernel file includes before its vector types and the traversal
// (bvh_wide_traverse.inl), so no header is compiled under a kernel's target attribute.
#pragma once

#include <cstdint>
#include <cstring>

#include "bvh_wide_kernels.hpp"
#include "kiln/formats/bvh_wide.hpp"
#include "kiln/runtime/bvh_wide.hpp"
#include "kiln/runtime/watertight.hpp"
#include "ray_box.hpp"
