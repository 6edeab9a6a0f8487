// `kiln render` of an event table (issue 18): a heatmap of the selected events' counts per
// Web-Mercator tile, on a log scale with a legend.
#pragma once

#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace kiln {
class Blob;
}

namespace kiln::cli {

struct EventRenderArgs {
  std::string time;                ///< "T0,T1" (ISO 8601 or Unix seconds), half-open
  std::vector<std::string> where;  ///< "NAME=LABEL,LABEL" each
  std::string box;                 ///< "min_lon,min_lat,max_lon,max_lat"
};

void add_event_render_options(CLI::App* command, EventRenderArgs& args);

/// Writes the heatmap PNG of a blob built from an event table, through its structure `accel`
/// (empty: the first that answers event queries), of size at most `size` ("WxH"); prints one
/// line about it. Returns the exit status (1 with one line on stderr on failure).
int run_event_render(const Blob& blob, const std::string& accel, const std::string& out,
                     const std::string& size, const EventRenderArgs& args);

}  // namespace kiln::cli
