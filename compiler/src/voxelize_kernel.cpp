// The choice of the voxelizer's small-triangle kernel (run-time CPU dispatch; KILN_VOXEL_KERNEL
// or set_voxel_kernel force one).
#include <atomic>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <string_view>

#include "kiln/compiler/voxelizer.hpp"
#include "voxelize_window.hpp"

namespace kiln {

namespace {

// The forced kernel (kAuto: none).
std::atomic<VoxelKernel> forced_kernel{VoxelKernel::kAuto};

VoxelKernel default_kernel() {
  if (const char* env = std::getenv("KILN_VOXEL_KERNEL"); env != nullptr && *env) {
    for (const VoxelKernel k : {VoxelKernel::kColumns, VoxelKernel::kAvx2, VoxelKernel::kAvx512})
      if (std::string_view(env) == voxel_kernel_name(k)) {
        if (!voxel_kernel_supported(k))
          throw std::invalid_argument(std::string("KILN_VOXEL_KERNEL=") + env +
                                      ": this CPU cannot run that kernel");
        return k;
      }
    throw std::invalid_argument(std::string("KILN_VOXEL_KERNEL=") + env +
                                ": not columns, avx2 or avx512");
  }
  for (const VoxelKernel k : {VoxelKernel::kAvx512, VoxelKernel::kAvx2})
    if (voxel_kernel_supported(k)) return k;
  return VoxelKernel::kColumns;
}

}  // namespace

const char* voxel_kernel_name(VoxelKernel kernel) {
  switch (kernel) {
    case VoxelKernel::kAuto:
      return "auto";
    case VoxelKernel::kColumns:
      return "columns";
    case VoxelKernel::kAvx2:
      return "avx2";
    case VoxelKernel::kAvx512:
      return "avx512";
  }
  return "?";
}

bool voxel_kernel_supported(VoxelKernel kernel) {
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
  switch (kernel) {
    case VoxelKernel::kAvx512:
      return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
             __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw") &&
             __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
             voxelize_detail::window_kernel_avx512() != nullptr;
    case VoxelKernel::kAvx2:
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
             voxelize_detail::window_kernel_avx2() != nullptr;
    default:
      return true;
  }
#else
  return kernel == VoxelKernel::kAuto || kernel == VoxelKernel::kColumns;
#endif
}

void set_voxel_kernel(VoxelKernel kernel) {
  if (!voxel_kernel_supported(kernel))
    throw std::invalid_argument(std::string("voxel kernel ") + voxel_kernel_name(kernel) +
                                ": this CPU cannot run it");
  forced_kernel.store(kernel, std::memory_order_relaxed);
}

VoxelKernel voxel_kernel() {
  const VoxelKernel forced = forced_kernel.load(std::memory_order_relaxed);
  if (forced != VoxelKernel::kAuto) return forced;
  static const VoxelKernel chosen = default_kernel();  // the environment is read once
  return chosen;
}

namespace voxelize_detail {

WindowKernel selected_window_kernel() {
  switch (voxel_kernel()) {
    case VoxelKernel::kAvx512:
      return window_kernel_avx512();
    case VoxelKernel::kAvx2:
      return window_kernel_avx2();
    default:
      return nullptr;
  }
}

}  // namespace voxelize_detail

}  // namespace kiln
