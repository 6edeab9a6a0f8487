// The page of `kiln serve` and its assets: the HTML, JS and CSS embedded in the binary at build
// time (tools/serve/page/), and Leaflet read once at start from Debian's libjs-leaflet, a path
// fixed here (not from a request).
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace kiln::serve {

struct Asset {
  std::string path;  ///< the URL path: "/", "/app.js", "/leaflet/leaflet.js", ...
  std::string type;  ///< media type
  std::string body;
};

/// Every asset the server serves; Leaflet's are left out (and the page says so) when Debian's
/// files are absent.
std::vector<Asset> load_assets();

/// Where Leaflet is read from.
inline constexpr std::string_view kLeafletDir = "/usr/share/javascript/leaflet";

}  // namespace kiln::serve
