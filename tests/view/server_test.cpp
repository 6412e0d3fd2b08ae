// The view server: routes, content types, the folder route's refusals (traversal, links, hidden
// files, listings), methods, Host checks, malformed requests, many clients at once, stopping with
// clients connected.

#include "hivox/view/server.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include "hivox/core/error.h"
#include "test_util.h"
#include "view/http_client.h"

namespace hivox {
namespace {

using test::get;

TEST(ViewServerParams, ParsesPortAddressAndBoth) {
  EXPECT_EQ(ViewServerParams::parse("").address, "127.0.0.1");
  EXPECT_EQ(ViewServerParams::parse("").port, 0);
  EXPECT_EQ(ViewServerParams::parse("8080").port, 8080);
  EXPECT_EQ(ViewServerParams::parse("8080").address, "127.0.0.1");
  const ViewServerParams any = ViewServerParams::parse("0.0.0.0:9000");
  EXPECT_EQ(any.address, "0.0.0.0");
  EXPECT_EQ(any.port, 9000);
  EXPECT_FALSE(any.loopback());
  EXPECT_TRUE(ViewServerParams::parse("localhost").loopback());
  EXPECT_EQ(ViewServerParams::parse("[::1]:80").address, "::1");
  for (const char* bad : {"70000", "host:", "host:port", "1.2.3.4:-1", ":"}) {
    try {
      ViewServerParams::parse(bad);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::InvalidArgument) << bad;
      EXPECT_TRUE(test::contains(e.what(), bad)) << e.what();
    }
  }
}

class ServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    test::write_text(dir_ / "run/stats.json", "{\"frames\": 3}");
    test::write_text(dir_ / "run/.hidden", "secret");
    test::write_text(dir_ / "run/sub/inner.txt", "inner");
    test::write_text(dir_ / "secret.txt", "outside the served folder");
    std::filesystem::create_symlink(dir_ / "secret.txt", dir_ / "run/link.txt");
    server_.route("/", [](const HttpQuery&) { return HttpReply{200, "text/html", "<p>page</p>"}; });
    server_.route("/api/echo.json", [](const HttpQuery& q) {
      return HttpReply::json("{\"n\": \"" + q.param("n", "none") + "\"}");
    });
    server_.route("/api/throws", [](const HttpQuery& q) -> HttpReply {
      if (q.param("kind") == "argument") fail(ErrorCode::InvalidArgument, "bad argument");
      throw std::runtime_error("handler failed");
    });
    server_.serve_folder("/files/", dir_ / "run");
    server_.start();
    port_ = server_.port();
  }
  test::TempDir dir_;
  ViewServer server_{ViewServerParams{}};
  int port_ = 0;
};

TEST_F(ServerTest, AnswersItsRoutesWithTheirTypes) {
  ASSERT_GT(port_, 0);
  EXPECT_EQ(server_.url(), "http://127.0.0.1:" + std::to_string(port_) + "/");
  auto r = get(port_, "/");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.header("Content-Type"), "text/html");
  EXPECT_EQ(r.body, "<p>page</p>");
  EXPECT_EQ(r.header("X-Content-Type-Options"), "nosniff");
  r = get(port_, "/api/echo.json?n=42");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.header("Content-Type"), "application/json");
  EXPECT_EQ(r.body, "{\"n\": \"42\"}");
  r = get(port_, "/files/stats.json");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.header("Content-Type"), "application/json");
  EXPECT_EQ(r.body, "{\"frames\": 3}");
  // The pages' own files, built in: three.js among them.
  r = get(port_, "/static/three.min.js");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.header("Content-Type"), "text/javascript; charset=utf-8");
  EXPECT_GT(r.body.size(), 100000u);
  EXPECT_TRUE(test::contains(r.body, "WebGLRenderer"));
  // Built-in files may be cached, data never; one Cache-Control each.
  EXPECT_EQ(r.header("Cache-Control"), "max-age=3600");
  EXPECT_EQ(r.head.find("Cache-Control"), r.head.rfind("Cache-Control"));
  EXPECT_EQ(get(port_, "/api/echo.json").header("Cache-Control"), "no-store");
  for (const char* asset : {"live.html", "live.js", "viewer.html", "viewer.js", "common.js",
                            "hivox.css", "OrbitControls.js"})
    EXPECT_EQ(get(port_, std::string("/static/") + asset).status, 200) << asset;
  EXPECT_EQ(get(port_, "/static/nothing.js").status, 404);
  EXPECT_EQ(get(port_, "/nothing").status, 404);
}

TEST_F(ServerTest, RefusesEverythingOutsideTheFolderAndNeverLists) {
  for (const char* target :
       {"/files/../secret.txt", "/files/%2e%2e/secret.txt", "/files/..%2fsecret.txt",
        "/files/%2e%2e%2fsecret.txt", "/files/link.txt", "/files/.hidden", "/files/sub",
        "/files/sub/inner.txt", "/files/", "/files", "/files//etc/passwd", "/files/%00stats.json",
        "/static/../files/stats.json", "/files/stats.json%00.png"}) {
    const auto r = get(port_, target);
    EXPECT_EQ(r.status, 404) << target;
    EXPECT_FALSE(test::contains(r.body, "outside the served folder")) << target;
    EXPECT_FALSE(test::contains(r.body, "inner")) << target;
  }
}

TEST_F(ServerTest, IsReadOnlyAndAnswersOnlyToLocalhost) {
  for (const char* method : {"POST", "PUT", "DELETE", "PATCH", "OPTIONS"}) {
    const auto r = test::send_raw(port_, std::string(method) +
                                             " /files/stats.json HTTP/1.1\r\nHost: "
                                             "127.0.0.1\r\nContent-Length: 0\r\nConnection: "
                                             "close\r\n\r\n");
    EXPECT_EQ(r.status, 405) << method;
    EXPECT_EQ(r.header("Allow"), "GET, HEAD") << method;
  }
  EXPECT_EQ(test::send_raw(port_, "HEAD / HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n")
                .status,
            200);
  // A page elsewhere that renamed its host to this address (DNS rebinding) is refused.
  EXPECT_EQ(get(port_, "/", "evil.example.com").status, 421);
  EXPECT_EQ(get(port_, "/", "localhost:" + std::to_string(port_)).status, 200);
}

TEST_F(ServerTest, BadRequestsGetAnErrorAndTheServerGoesOn) {
  EXPECT_EQ(get(port_, "/api/throws?kind=argument").status, 400);
  const auto failed = get(port_, "/api/throws");
  EXPECT_EQ(failed.status, 500);
  EXPECT_TRUE(test::contains(failed.body, "handler failed"));
  for (const std::string& garbage :
       {std::string("\x00\x01\x02\xff\r\n\r\n", 8), std::string("GET\r\n\r\n"),
        std::string("GET / HTTP/9.9\r\n\r\n"), std::string(100000, 'A'),
        std::string("GET /") + std::string(20000, 'a') + " HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n",
        std::string("POST / HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 99999999\r\n\r\nx")}) {
    const auto r = test::send_raw(port_, garbage);
    EXPECT_TRUE(r.status == 0 || r.status >= 400) << r.status << " for " << garbage.substr(0, 40);
  }
  EXPECT_EQ(get(port_, "/").status, 200);
  EXPECT_TRUE(server_.running());
  EXPECT_GT(server_.refused(), 0);
}

TEST_F(ServerTest, ServesManyClientsAtOnce) {
  std::atomic<int> ok{0};
  std::vector<std::thread> clients;
  for (int c = 0; c < 16; ++c)
    clients.emplace_back([&, c] {
      for (int i = 0; i < 10; ++i)
        if (get(port_, "/api/echo.json?n=" + std::to_string(c * 100 + i)).body ==
            "{\"n\": \"" + std::to_string(c * 100 + i) + "\"}")
          ++ok;
    });
  for (std::thread& t : clients) t.join();
  EXPECT_EQ(ok.load(), 160);
}

TEST_F(ServerTest, StopsPromptlyWithAClientConnected) {
  // A client holds a kept-alive connection open (and another sends half a request).
  const auto open_connection = [&](const std::string& bytes) {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<uint16_t>(port_));
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
    (void)!write(fd, bytes.data(), bytes.size());
    return fd;
  };
  const int kept = open_connection("GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
  const int half = open_connection("GET / HTTP/1.1\r\nHost: 127");
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  const auto start = std::chrono::steady_clock::now();
  server_.stop();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(seconds, 7.0);
  EXPECT_FALSE(server_.running());
  EXPECT_EQ(get(port_, "/").status, 0);  // nobody listens any more
  close(kept);
  close(half);
  server_.stop();  // idempotent
}

TEST(ViewServer, APortInUseIsAClearError) {
  ViewServer first{ViewServerParams{}};
  first.start();
  ViewServerParams p;
  p.port = first.port();
  ViewServer second{p};
  try {
    second.start();
    FAIL() << "a second server started on port " << p.port;
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::Io);
    EXPECT_TRUE(test::contains(e.what(), "127.0.0.1:" + std::to_string(p.port))) << e.what();
  }
}

}  // namespace
}  // namespace hivox
