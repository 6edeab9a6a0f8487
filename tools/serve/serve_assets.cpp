// The embedded page (serve_page_data.cpp is generated from tools/serve/page/ by
// embed_assets.cmake) and Leaflet's files read from their fixed Debian path.
#include "serve_assets.hpp"

#include <fstream>
#include <sstream>

namespace kiln::serve {

// Generated: the page's files, in serve_page_data.cpp.
extern const char* const kPageIndexHtml;
extern const char* const kPageAppJs;
extern const char* const kPageAppCss;

namespace {

bool read_whole(const std::string& path, std::string& out) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  std::ostringstream text;
  text << in.rdbuf();
  out = text.str();
  return true;
}

}  // namespace

std::vector<Asset> load_assets() {
  std::vector<Asset> assets = {{"/", "text/html; charset=utf-8", kPageIndexHtml},
                               {"/app.js", "application/javascript", kPageAppJs},
                               {"/app.css", "text/css", kPageAppCss}};
  const std::string dir(kLeafletDir);
  const std::pair<const char*, const char*> leaflet[] = {
      {"leaflet.js", "application/javascript"}, {"leaflet.css", "text/css"},
      {"images/layers.png", "image/png"},       {"images/layers-2x.png", "image/png"},
      {"images/marker-icon.png", "image/png"},  {"images/marker-shadow.png", "image/png"}};
  for (const auto& [file, type] : leaflet) {
    Asset a{"/leaflet/" + std::string(file), type, {}};
    if (read_whole(dir + "/" + file, a.body)) assets.push_back(std::move(a));
  }
  return assets;
}

}  // namespace kiln::serve
