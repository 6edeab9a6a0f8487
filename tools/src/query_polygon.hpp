// `kiln query --op polygon | polygons-in-box`: point in polygon and features meeting boxes, on
// whichever structure of the blob answers polygon queries (PolygonQueries).
#pragma once

#include <string>

#include <CLI/CLI.hpp>

namespace kiln::cli {

struct PolygonQueryArgs {
  std::string blob, op, in, out, accel;
  std::string lon_column = "longitude", lat_column = "latitude";
  bool all = false;
  unsigned threads = 0;
};

/// Whether `op` is one of the polygon queries.
bool is_polygon_op(const std::string& op);
/// --all, --lon-column, --lat-column (written into `args`).
void add_polygon_query_options(CLI::App* command, PolygonQueryArgs& args);
/// Runs the query; one line on stderr and 1 on failure.
int run_polygon_query(const PolygonQueryArgs& args);

}  // namespace kiln::cli
