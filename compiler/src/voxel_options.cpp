#include "voxel_options.hpp"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <memory>
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
          "(dag and ssvdag: 8..131072, built out of core)",
          false,
          parse};
}

std::uint64_t parse_memory_size(std::string_view text) {
  std::uint64_t n = 0;
  const char* end = text.data() + text.size();
  const auto [rest, error] = std::from_chars(text.data(), end, n);
  if (rest == text.data()) throw std::invalid_argument("not a size (e.g. 8G, 512M, 1000000)");
  std::string unit(rest, end);
  for (char& c : unit) c = char(std::toupper(static_cast<unsigned char>(c)));
  if (unit.size() >= 2 && unit.substr(unit.size() - 2) == "IB")
    unit.resize(unit.size() - 2);
  else if (unit.size() >= 2 && unit.back() == 'B')
    unit.pop_back();
  static constexpr std::string_view kUnits = "KMGT";
  int shift = 0;
  if (unit.size() == 1 && kUnits.find(unit[0]) != std::string_view::npos)
    shift = 10 * int(kUnits.find(unit[0]) + 1);
  else if (!unit.empty() && unit != "B")
    throw std::invalid_argument("unknown unit '" + std::string(rest, end) + "' (use K, M, G or T)");
  if (error != std::errc() || (shift > 0 && n > (~std::uint64_t(0) >> shift)))
    throw std::invalid_argument("too large");
  if (n == 0) throw std::invalid_argument("must be more than zero");
  return n << shift;
}

std::uint64_t default_memory_budget() {
  constexpr std::uint64_t kGiB = std::uint64_t(1) << 30;
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
  if (pages <= 0 || page <= 0) return kGiB;
  return std::min(std::uint64_t(pages) * std::uint64_t(page) / 2, 8 * kGiB);
}

StructureOption memory_budget_option() {
  auto parse = [](std::string_view text) {
    if (text == "auto") return std::string("auto");
    return std::to_string(parse_memory_size(text));
  };
  StructureOption option{
      "memory-budget",
      "--memory-budget",
      "auto",
      "--accel dag, esvo: bytes the build may hold at once, e.g. 8G or 512M (K, M, G, T: "
      "powers of 1024); auto: half the memory, at most 8G. Never changes "
      "the output",
      false,
      parse};
  option.enters_output = false;
  return option;
}

std::uint64_t memory_budget_bytes(const std::string& canonical) {
  return canonical == "auto" ? default_memory_budget() : parse_memory_size(canonical);
}

// "dag: cube 12/512, 31 % of voxels, ETA 1m20s" on one line of a terminal, rewritten in place
// at most 4 times a second once the build has run for a second (as kiln build's own line).
std::function<void(std::uint64_t, std::uint64_t, double)> terminal_progress() {
  if (!isatty(STDERR_FILENO)) return {};
  using Clock = std::chrono::steady_clock;
  auto last = std::make_shared<Clock::time_point>(Clock::now());
  return [start = Clock::now(), last](std::uint64_t done, std::uint64_t total, double share) {
    const auto now = Clock::now();
    const bool end = done == total;
    if (now - start < std::chrono::seconds(1) ||
        (!end && now - *last < std::chrono::milliseconds(250)))
      return;
    *last = now;
    const double elapsed = std::chrono::duration<double>(now - start).count();
    const double eta = share > 0 ? elapsed * (1 - share) / share : 0;
    std::fprintf(stderr, "\r\033[Kdag: cube %llu/%llu, %.0f %% of voxels, ETA %dm%02ds%s",
                 (unsigned long long)done, (unsigned long long)total, 100 * share, int(eta / 60),
                 int(eta) % 60, end ? "\n" : "");
    std::fflush(stderr);
  };
}

}  // namespace kiln
