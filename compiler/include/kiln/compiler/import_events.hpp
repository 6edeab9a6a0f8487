// Importing a CSV file as an event table (`kiln build --lat --lon --time [--category ...]`).
#pragma once

#include <string>
#include <vector>

#include "kiln/compiler/event_table.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/compiler/scene.hpp"

namespace kiln {

/// Reads `path` (inflating .zst) as an event table into a Scene (`events`, `sources`,
/// `accessed`). Throws ImportError with one line ("path:LINE: column 'time': ...").
Scene import_events(const std::string& path, const EventColumns& columns,
                    const ImportLimits& limits);

/// What `kiln build` does with event columns given: exactly one input, read by import_events.
Scene import_event_scene(const std::vector<std::string>& inputs, const EventColumns& columns,
                         const ImportLimits& limits);

}  // namespace kiln
