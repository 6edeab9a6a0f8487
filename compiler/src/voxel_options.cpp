#include "voxel_options.hpp"

#include <charconv>
#include <stdexcept>
#include <string>

#include "kiln/formats/voxel_grid.hpp"

namespace kiln {

StructureOption voxel_resolution_option(std::uint32_t max) {
  auto parse = [max](std::string_view text) {
    std::uint32_t n = 0;
    const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), n);
    if (text.empty() || error == std::errc::invalid_argument || end != text.data() + text.size())
      throw std::invalid_argument("not an integer");
    if (error != std::errc() || !format::is_valid_voxel_resolution(n, max))
      throw std::invalid_argument("must be a power of two in " +
                                  std::to_string(format::kVoxelMinResolution) + ".." +
                                  std::to_string(max));
    return std::to_string(n);
  };
  return {"resolution",
          "--resolution",
          "512",
          "Voxel grid side (finest level) of the voxel structures: a power of two, 8..16384 "
          "(dag: 8..131072, built out of core)",
          false,
          parse};
}

}  // namespace kiln
