// A bound on the element counts in a Draco stream's header, checked before Draco allocates for
// them.
#pragma once

#include <cstddef>
#include <span>
#include <string>

namespace kiln {

// Throws ImportError ("path: Draco: claims N faces, more than a stream of B bytes can encode")
// when a count in the header of the Draco stream `bytes` exceeds 1024 per byte of the stream (at
// least 4096 bytes' worth). A stream that does not start with "DRACO" is left to Draco.
void check_draco_counts(const std::string& path, std::span<const std::byte> bytes);

}  // namespace kiln
