// `kiln serve BLOB... [--bind 127.0.0.1] [--port 8080] [--threads N]`: maps the blobs, serves the
// JSON API, tiles and the page until SIGINT or SIGTERM, then lets in-flight requests finish and
// exits 0.
#include <pthread.h>
#include <signal.h>

#include <atomic>
#include <ctime>
#include <iostream>
#include <memory>
#include <thread>

#include "../src/commands.hpp"
#include "serve_server.hpp"

namespace kiln::cli {

namespace {

struct ServeArgs {
  std::vector<std::string> blobs;
  serve::ServerOptions options;
};

sigset_t stop_signals() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  return set;
}

int run_serve(const ServeArgs& args) {
  // Blocked before any thread starts, so every thread inherits the mask and only the watcher
  // below receives the signals (sigtimedwait), never a request thread mid-body.
  const sigset_t set = stop_signals();
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
  try {
    const serve::Catalog catalog(args.blobs);
    serve::Server server(catalog, args.options);
    server.bind();
    std::string names;
    for (const auto& b : catalog.blobs()) names += (names.empty() ? "" : ", ") + b.name;
    std::cout << "kiln serve: http://" << args.options.bind << ":" << server.port() << "/ ("
              << names << "); Ctrl-C stops" << std::endl;
    std::atomic<bool> done{false};
    std::thread watcher([&] {
      const timespec tick{0, 200'000'000};
      while (!done.load()) {
        if (sigtimedwait(&set, nullptr, &tick) > 0) {
          server.stop();
          return;
        }
      }
    });
    const bool ok = server.run();
    done = true;
    watcher.join();
    if (!ok) throw std::runtime_error("the server stopped on a socket error");
    std::cout << "kiln serve: stopped" << std::endl;
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "kiln serve: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace

Command add_serve_command(CLI::App& app) {
  auto args = std::make_shared<ServeArgs>();
  auto* command = app.add_subcommand(
      "serve", "Serve blobs over HTTP: a JSON query API, map tiles and an exploration page");
  command->add_option("blob", args->blobs, "The .kiln files (served by file name without .kiln)")
      ->required();
  command->add_option("--bind", args->options.bind, "Address to listen on (default loopback)");
  command->add_option("--port", args->options.port, "TCP port (0: any free port)")
      ->check(CLI::Range(0, 65535));
  add_threads_option(command, args->options.threads,
                     "Request threads, each serving one connection at a time (0 = 16)");
  return {command, [args] { return run_serve(*args); }};
}

}  // namespace kiln::cli
