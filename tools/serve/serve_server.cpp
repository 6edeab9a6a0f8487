// cpp-httplib wiring: each route hands its request to serve_api.cpp (or the assets) and sends
// the answer; errors httplib makes itself (unknown path 404, body over the limit 413) get a JSON
// body too. httplib compresses text and JSON answers with gzip when the client accepts it.
#include "serve_server.hpp"

#include <httplib.h>

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
    const unsigned threads =
        options.threads ? options.threads : std::max(2u, std::thread::hardware_concurrency());
    // The pool size compiled into Debian's .so is 8 whatever the macro says: set it here.
    http.new_task_queue = [threads] { return new httplib::ThreadPool(threads); };
    http.set_payload_max_length(options.limits.max_request_bytes);
    http.set_read_timeout(5, 0);
    http.set_write_timeout(5, 0);
    http.set_keep_alive_max_count(1000);
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
}

bool Server::run() {
  return impl_->http.listen_after_bind();
}

void Server::stop() {
  impl_->http.stop();
}

}  // namespace kiln::serve
