#include "hivox/view/server.h"

#include <httplib.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <chrono>
#include <system_error>
#include <thread>
#include <vector>

#include "hivox/core/error.h"
#include "view/assets.h"

namespace hivox {

namespace fs = std::filesystem;

ViewServerParams ViewServerParams::parse(std::string_view text) {
  ViewServerParams p;
  auto parse_port = [&](std::string_view digits) {
    int port = -1;
    const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), port);
    if (digits.empty() || ec != std::errc() || end != digits.data() + digits.size())
      fail(ErrorCode::InvalidArgument,
           "view address '{}': expected PORT, ADDRESS or ADDRESS:PORT (e.g. 8080, "
           "0.0.0.0:8080; write --view=ADDR:PORT, or --view after the dataset, so that the "
           "dataset is not taken for it)",
           text);
    return port;
  };
  if (text.empty()) return p;
  const std::size_t colon = text.rfind(':');
  const bool all_digits = std::all_of(
      text.begin(), text.end(), [](char c) { return std::isdigit(static_cast<unsigned char>(c)); });
  if (all_digits) {
    p.port = parse_port(text);
  } else if (colon == std::string_view::npos) {
    p.address = std::string(text);
  } else {
    p.address = std::string(text.substr(0, colon));
    p.port = parse_port(text.substr(colon + 1));
  }
  if (p.address.size() > 2 && p.address.front() == '[' && p.address.back() == ']')
    p.address = p.address.substr(1, p.address.size() - 2);
  try {
    p.validate();
  } catch (const Error& e) {
    fail(ErrorCode::InvalidArgument, "view address '{}': {}", text, e.what());
  }
  return p;
}

void ViewServerParams::validate() const {
  if (port < 0 || port > 65535)
    fail(ErrorCode::InvalidArgument, "view port must be in 0..65535 (0 = a free one), got {}",
         port);
  if (address.empty()) fail(ErrorCode::InvalidArgument, "view address is empty");
  if (threads < 1 || threads > 64)
    fail(ErrorCode::InvalidArgument, "view server threads must be in 1..64, got {}", threads);
}

bool ViewServerParams::loopback() const {
  return address == "localhost" || address == "::1" || address.rfind("127.", 0) == 0;
}

std::string HttpQuery::param(const std::string& name, const std::string& fallback) const {
  const auto it = params.find(name);
  return it == params.end() ? fallback : it->second;
}

std::string_view content_type_for(const fs::path& name) {
  const std::string ext = name.extension().string();
  if (ext == ".html") return "text/html; charset=utf-8";
  if (ext == ".js") return "text/javascript; charset=utf-8";
  if (ext == ".css") return "text/css; charset=utf-8";
  if (ext == ".json") return "application/json";
  if (ext == ".png") return "image/png";
  if (ext == ".jpg" || ext == ".jpeg") return "image/jpeg";
  if (ext == ".txt" || ext == ".md") return "text/plain; charset=utf-8";
  return "application/octet-stream";
}

namespace {

/// A file name the folder route may serve: letters, digits, '.', '-', '_', not starting with
/// '.' (no "..", no hidden files, no separators).
bool plain_file_name(std::string_view name) {
  if (name.empty() || name.size() > 255 || name.front() == '.') return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '-' || c == '_';
  });
}

/// The host part of a Host header ("127.0.0.1:8080" -> "127.0.0.1", "[::1]:80" -> "::1").
std::string host_name(const std::string& header) {
  if (!header.empty() && header.front() == '[') {
    const std::size_t close = header.find(']');
    return close == std::string::npos ? header : header.substr(1, close - 1);
  }
  return header.substr(0, header.find(':'));
}

}  // namespace

struct ViewServer::Impl {
  httplib::Server server;
  std::map<std::string, Handler> routes;
  std::string folder_prefix;
  fs::path folder;  ///< canonical
  std::thread thread;
  bool started = false;
};

ViewServer::ViewServer(const ViewServerParams& params)
    : impl_(std::make_unique<Impl>()), params_(params) {
  params_.validate();
}

ViewServer::~ViewServer() {
  stop();
}

void ViewServer::route(const std::string& path, Handler handler) {
  impl_->routes[path] = std::move(handler);
}

void ViewServer::serve_folder(const std::string& prefix, const fs::path& dir) {
  std::error_code ec;
  impl_->folder = fs::canonical(dir, ec);
  if (ec) fail(ErrorCode::Io, "{}: cannot serve this folder ({})", dir.string(), ec.message());
  impl_->folder_prefix = prefix;
}

void ViewServer::start() {
  if (impl_->started) return;
  Impl& s = *impl_;
  const int threads = params_.threads;
  s.server.new_task_queue = [threads] {
    return new httplib::ThreadPool(static_cast<std::size_t>(threads));
  };
  s.server.set_keep_alive_timeout(1);
  s.server.set_read_timeout(2);
  s.server.set_write_timeout(5);
  s.server.set_payload_max_length(64 * 1024);
  // SO_REUSEADDR only: with SO_REUSEPORT (the library's default) a second server could bind the
  // same port and share its requests unnoticed.
  s.server.set_socket_options([](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, reinterpret_cast<const void*>(&yes), sizeof yes);
  });
  const bool loopback = params_.loopback();
  // Every request goes through here: the routes are exact paths, the rest is refused.
  s.server.set_pre_routing_handler([this, loopback](const httplib::Request& req,
                                                    httplib::Response& res) {
    ++requests_;
    // The page's built-in files may be cached; data and the run's files change: never.
    auto reply = [&](const HttpReply& r, bool cacheable = false) {
      res.status = r.status;
      res.set_content(r.body, r.content_type);
      res.set_header("X-Content-Type-Options", "nosniff");
      res.set_header("Referrer-Policy", "no-referrer");
      res.set_header("Cache-Control", cacheable ? "max-age=3600" : "no-store");
      if (r.status >= 400) ++refused_;
      return httplib::Server::HandlerResponse::Handled;
    };
    if (req.method != "GET" && req.method != "HEAD") {
      res.set_header("Allow", "GET, HEAD");
      return reply(HttpReply::error(405, "only GET and HEAD: this server is read-only"));
    }
    if (loopback) {
      const std::string host = host_name(req.get_header_value("Host"));
      if (host != "localhost" && host != "::1" && host.rfind("127.", 0) != 0)
        return reply(HttpReply::error(421, "this server answers only to localhost"));
    }
    HttpQuery q;
    q.path = req.path;
    for (const auto& [k, v] : req.params) q.params.emplace(k, v);
    try {
      if (const auto it = impl_->routes.find(q.path); it != impl_->routes.end())
        return reply(it->second(q));
      constexpr std::string_view kStatic = "/static/";
      if (q.path.rfind(kStatic, 0) == 0) {
        const std::string name = q.path.substr(kStatic.size());
        if (const auto asset = view::static_asset(name); asset && plain_file_name(name))
          return reply({200, std::string(content_type_for(name)), std::string(*asset)}, true);
        return reply(HttpReply::error(404, "no such file"));
      }
      const std::string& prefix = impl_->folder_prefix;
      if (!prefix.empty() && q.path.rfind(prefix, 0) == 0) {
        const std::string name = q.path.substr(prefix.size());
        if (!plain_file_name(name)) return reply(HttpReply::error(404, "no such file"));
        std::error_code ec;
        const fs::path file = fs::canonical(impl_->folder / name, ec);
        if (ec || file.parent_path() != impl_->folder || !fs::is_regular_file(file, ec))
          return reply(HttpReply::error(404, "no such file"));
        std::string body;
        if (std::FILE* f = std::fopen(file.c_str(), "rb")) {
          char buffer[1 << 16];
          std::size_t n;
          while ((n = std::fread(buffer, 1, sizeof buffer, f)) > 0) body.append(buffer, n);
          std::fclose(f);
        } else {
          return reply(HttpReply::error(404, "no such file"));
        }
        return reply({200, std::string(content_type_for(file)), std::move(body)});
      }
      return reply(HttpReply::error(404, "no such page"));
    } catch (const Error& e) {
      return reply(HttpReply::error(e.code() == ErrorCode::InvalidArgument ? 400 : 500, e.what()));
    } catch (const std::exception& e) {
      return reply(HttpReply::error(500, e.what()));
    }
  });
  const int port = params_.port == 0
                       ? s.server.bind_to_any_port(params_.address)
                       : (s.server.bind_to_port(params_.address, params_.port) ? params_.port : -1);
  if (port <= 0)
    fail(ErrorCode::Io,
         "view server: cannot listen on {}:{} (port taken, or not an address of this machine)",
         params_.address, params_.port);
  port_ = port;
  s.thread = std::thread([&s] { s.server.listen_after_bind(); });
  s.started = true;
  // Until the thread listens, a stop() would not reach it (and it would listen for ever).
  for (int i = 0; i < 5000 && !s.server.is_running(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
}

void ViewServer::stop() {
  if (!impl_ || !impl_->started) return;
  impl_->server.stop();
  if (impl_->thread.joinable()) impl_->thread.join();
  impl_->started = false;
}

bool ViewServer::running() const {
  return impl_->started && impl_->server.is_running();
}

std::string ViewServer::url() const {
  std::string host = params_.address;
  if (host == "0.0.0.0" || host == "::") host = "127.0.0.1";
  if (host.find(':') != std::string::npos) host = "[" + host + "]";
  return "http://" + host + ":" + std::to_string(port_) + "/";
}

}  // namespace hivox
