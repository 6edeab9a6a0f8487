// cpp-httplib wiring: each route hands its request to serve_api.cpp (or the assets) and sends
// the answer; errors httplib makes itself (unknown path 404, body over the limit 413) get a JSON
// body too. httplib compresses text and JSON answers with gzip when the client accepts it.
#include "serve_server.hpp"

#include <httplib.h>
#include <sys/socket.h>

#include <algorithm>
#include <stdexcept>
#include <thread>

#include "serve_assets.hpp"

namespace kiln::serve {

struct Server::Impl {
  const Catalog& catalog;
  ServerOptions options;
  std::vector<Asset> assets = load_assets();
  httplib::Server http;
  int listen_socket = -1;  // seen when httplib creates it, to raise its backlog after bind

  Impl(const Catalog& c, ServerOptions o) : catalog(c), options(std::move(o)) {}

  static void send(httplib::Response& res, const Response& r) {
    res.status = r.status;
    res.set_content(r.body, r.type.c_str());
  }

  void routes() {
    http.Get("/api/blobs", [this](const httplib::Request&, httplib::Response& res) {
      send(res, {200, catalog.describe().dump(-1, ' ', false,
                                              nlohmann::json::error_handler_t::replace)});
    });
    http.Post("/api/query", [this](const httplib::Request& req, httplib::Response& res) {
      send(res, query_request(catalog, req.body, options.limits));
    });
    http.Get(R"(/tiles/([^/]+)/([0-9]+)/([0-9]+)/([0-9]+)\.png)",
             [this](const httplib::Request& req, httplib::Response& res) {
               const std::multimap<std::string, std::string> params(req.params.begin(),
                                                                    req.params.end());
               send(res, tile_request(catalog, req.matches[1].str(), req.matches[2].str(),
                                      req.matches[3].str(), req.matches[4].str(), params));
             });
    for (const Asset& asset : assets)
      http.Get(asset.path, [&asset](const httplib::Request&, httplib::Response& res) {
        res.set_content(asset.body, asset.type.c_str());
      });
  }

  void settings() {
    const unsigned threads = options.threads ? options.threads : kDefaultThreads;
    // The pool size compiled into Debian's .so is 8 whatever the macro says: set it here.
    http.new_task_queue = [threads] { return new httplib::ThreadPool(threads); };
    http.set_payload_max_length(options.limits.max_request_bytes);
    http.set_read_timeout(5, 0);
    http.set_write_timeout(5, 0);
    // A worker serves one connection at a time (httplib's model): a connection gives its worker
    // back after a few requests or a short idle wait, so 32 clients (or a browser's idle
    // connections) on a few threads all get served.
    http.set_keep_alive_max_count(8);
    http.set_keep_alive_timeout(1);
    // Headers and body leave in separate writes: without TCP_NODELAY, Nagle's algorithm and the
    // client's delayed ACK hold the body back some 40 ms.
    http.set_tcp_nodelay(true);
    http.set_socket_options([this](socket_t sock) {
      httplib::default_socket_options(sock);
      listen_socket = sock;
    });
    http.set_error_handler([](const httplib::Request& req, httplib::Response& res) {
      if (!res.body.empty()) return;  // a route's own JSON error
      const std::string what = res.status == 404   ? "no such path: " + req.path
                               : res.status == 413 ? "request too large"
                                                   : "HTTP " + std::to_string(res.status);
      res.set_content(error_response(res.status, what).body, "application/json");
    });
    http.set_exception_handler(
        [](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
          std::string what = "internal error";
          try {
            std::rethrow_exception(ep);
          } catch (const std::exception& e) {
            what += std::string(": ") + e.what();
          } catch (...) {
          }
          res.status = 500;
          res.set_content(error_response(500, what).body, "application/json");
        });
  }
};

Server::Server(const Catalog& catalog, ServerOptions options)
    : impl_(std::make_unique<Impl>(catalog, std::move(options))) {
  impl_->routes();
  impl_->settings();
}

Server::~Server() = default;

void Server::bind() {
  const ServerOptions& o = impl_->options;
  port_ = o.port == 0 ? impl_->http.bind_to_any_port(o.bind.c_str())
                      : (impl_->http.bind_to_port(o.bind.c_str(), o.port) ? o.port : -1);
  if (port_ <= 0)
    throw std::runtime_error("cannot listen on " + o.bind + ":" + std::to_string(o.port));
  // httplib listens with a backlog of 5: 32 clients connecting at once overflow it and wait a
  // second for their SYN to be sent again. Listening again on Linux only raises the backlog.
  if (impl_->listen_socket >= 0) ::listen(impl_->listen_socket, SOMAXCONN);
}

bool Server::run() {
  return impl_->http.listen_after_bind();
}

void Server::stop() {
  impl_->http.stop();
}

}  // namespace kiln::serve
