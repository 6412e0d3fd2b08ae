#pragma once
/// @file
/// The HTTP server behind `hivox reconstruct --view` and `hivox view`: a small read-only server
/// for one page, its scripts and the data it shows. It answers GET (and HEAD) only, on routes
/// registered by exact path and on the plain files directly inside one folder; every other
/// request gets an error status, never a crash. It binds to loopback unless told otherwise, and
/// then also refuses requests whose Host header names another machine (a page elsewhere cannot
/// read it through DNS rebinding). Requests are served on the server's own threads: a handler
/// must not block on the caller's work (the live view hands it finished snapshots).

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <string_view>

namespace hivox {

struct ViewServerParams {
  /// Address to listen on: "127.0.0.1" (this machine only), "0.0.0.0" for every interface.
  std::string address = "127.0.0.1";
  int port = 0;     ///< 0 = a free port chosen at start
  int threads = 4;  ///< requests served at once (more wait in the queue)

  /// "PORT", "ADDR", "ADDR:PORT" or "" (the defaults); throws `Error(InvalidArgument)` naming
  /// the text otherwise.
  static ViewServerParams parse(std::string_view text);
  /// Throws `Error(InvalidArgument)` naming the bad setting.
  void validate() const;
  bool loopback() const;
};

/// A request as a handler sees it: the decoded path and the query parameters.
struct HttpQuery {
  std::string path;
  std::map<std::string, std::string> params;
  /// The parameter `name`, or `fallback` when absent.
  std::string param(const std::string& name, const std::string& fallback = "") const;
};

/// What a handler answers.
struct HttpReply {
  int status = 200;
  std::string content_type = "application/json";
  std::string body;
  static HttpReply json(std::string body) { return {200, "application/json", std::move(body)}; }
  static HttpReply error(int status, std::string message) {
    return {status, "text/plain; charset=utf-8", std::move(message) + "\n"};
  }
};

class ViewServer {
 public:
  using Handler = std::function<HttpReply(const HttpQuery&)>;

  explicit ViewServer(const ViewServerParams& params);
  ~ViewServer();  ///< stops the server
  ViewServer(const ViewServer&) = delete;
  ViewServer& operator=(const ViewServer&) = delete;

  /// Answers GET `path` (exact, e.g. "/api/status.json") with `handler`. A handler that throws
  /// gives status 500 with the exception's message. Register before start().
  void route(const std::string& path, Handler handler);
  /// Serves the regular files directly inside `dir` as `prefix` + name (e.g. "/files/mesh.ply"):
  /// names of letters, digits, '.', '-' and '_' that do not start with '.'; nothing in
  /// sub-folders, no listing, no link leading out of `dir`.
  void serve_folder(const std::string& prefix, const std::filesystem::path& dir);
  /// The page's own files (scripts, style, three.js), built into the program, are always
  /// served under "/static/".

  /// Binds and starts serving on background threads. Throws `Error(Io)` naming the address and
  /// port when it cannot listen there (taken, not an address of this machine).
  void start();
  /// Stops listening and returns once the server's threads have ended (connected clients are
  /// let go within a second). Idempotent.
  void stop();
  bool running() const;

  int port() const { return port_; }
  /// "http://ADDR:PORT/" (with a loopback name a browser accepts).
  std::string url() const;
  /// Requests answered, and of them those refused (4xx, 5xx).
  int64_t requests() const { return requests_.load(); }
  int64_t refused() const { return refused_.load(); }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  ViewServerParams params_;
  int port_ = 0;
  std::atomic<int64_t> requests_{0}, refused_{0};
};

/// The content type a browser needs for a file name's extension (octet-stream when unknown).
std::string_view content_type_for(const std::filesystem::path& name);

}  // namespace hivox
