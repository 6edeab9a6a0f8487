// The event table input's raw sections (docs/FORMAT.md, "Event tables"): one row per event,
// column by column, so a brute-force scan of the mapped table reads only the columns it needs.
#pragma once

#include <cstdint>

#include "kiln/formats/container.hpp"

namespace kiln::format {

inline constexpr std::uint32_t kSectionEventPoints = fourcc('E', 'V', 'L', 'L');  // Double2 lon/lat
inline constexpr std::uint32_t kSectionEventTimes = fourcc('E', 'V', 'T', 'M');   // int64 Unix s
/// uint32 label codes, category-major: the code of row r in category c is [c * rows + r].
inline constexpr std::uint32_t kSectionEventCodes = fourcc('E', 'V', 'C', 'D');
/// Every category's labels, one string table (uint64 offsets, labels_total + 1; UTF-8 bytes).
inline constexpr std::uint32_t kSectionEventLabelOffsets = fourcc('E', 'V', 'L', 'O');
inline constexpr std::uint32_t kSectionEventLabelBytes = fourcc('E', 'V', 'L', 'B');

}  // namespace kiln::format
