// `kiln serve`'s HTTP side (cpp-httplib 0.11 from Debian): routes, a fixed thread pool,
// limits, JSON errors, gzip when the client accepts it, and a clean stop.
#pragma once

#include <memory>
#include <string>

#include "serve_api.hpp"
#include "serve_catalog.hpp"

namespace kiln::serve {

/// Request threads by default: a thread serves one connection at a time, and a browser opens
/// several (tiles), so more threads than cores.
inline constexpr unsigned kDefaultThreads = 16;

struct ServerOptions {
  std::string bind = "127.0.0.1";
  int port = 8080;       ///< 0: any free port (see Server::port)
  unsigned threads = 0;  ///< request threads; 0: kDefaultThreads
  Limits limits;
};

/// An HTTP server over a catalog: GET /api/blobs, POST /api/query, GET /tiles/..., GET / and the
/// page's assets (embedded, or Leaflet from its fixed Debian path). Never opens a path a
/// request names.
class Server {
 public:
  Server(const Catalog& catalog, ServerOptions options);
  ~Server();
  /// Binds (throws std::runtime_error with one line when it cannot).
  void bind();
  /// The bound port (after bind).
  int port() const { return port_; }
  /// Serves until stop(); in-flight requests finish first. Returns false on a socket error.
  bool run();
  /// Stops run() from any thread (signal watchers, tests).
  void stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  int port_ = 0;
};

}  // namespace kiln::serve
