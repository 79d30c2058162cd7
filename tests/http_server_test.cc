// Integration test of the reconduit-server binary: starts it as a child process on a free port
// with a temporary data folder and checks its behaviour over real sockets.
#include "server/http/test_client.h"
#include "tests/server_process.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <poll.h>
#include <signal.h>
#include <sstream>
#include <string>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>
#include <vector>

namespace reconduit::server {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

// The shared launcher, bound to this build's server binary.
class ServerProcess : public testing_util::ServerProcess {
 public:
  ServerProcess() : testing_util::ServerProcess(RECONDUIT_SERVER_BINARY) {}
};

class HttpServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("reconduit_http_server_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "web");
    std::ofstream(dir_ / "web" / "index.html") << "<!doctype html><title>Reconduit</title>";
    std::ofstream(dir_ / "secret.txt") << "top secret";
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::vector<std::string> BaseArgs() const {
    return {"--host",    "127.0.0.1",
            "--port",    "0",
            "--data",    (dir_ / "data").string(),
            "--web",     (dir_ / "web").string(),
            "--threads", "2"};
  }

  fs::path dir_;
};

nlohmann::json Json(const TestResponse& response) {
  return nlohmann::json::parse(response.body, nullptr, /*allow_exceptions=*/false);
}

TEST_F(HttpServerTest, ServesHealthStaticFilesAndErrors) {
  ServerProcess server;
  // max-upload-bytes comes from the environment, to check that mapping too.
  ASSERT_TRUE(server.Start(BaseArgs(), dir_ / "stderr.txt", {"RECONDUIT_MAX_UPLOAD_BYTES=1000"}))
      << server.error();
  ASSERT_TRUE(server.WaitUntilHealthy()) << server.Stderr();
  EXPECT_TRUE(fs::is_directory(dir_ / "data"));
  const int port = server.port();

  TestResponse health = Fetch(port, "GET", "/healthz");
  EXPECT_EQ(health.status, 200u);
  EXPECT_EQ(Json(health), (nlohmann::json{{"status", "ok"}}));
  EXPECT_EQ(health.Header("Content-Type"), "application/json");
  EXPECT_EQ(health.Header("Server").rfind("reconduit/", 0), 0u);
  EXPECT_FALSE(health.Header("X-Request-Id").empty());

  TestResponse index = Fetch(port, "GET", "/");
  EXPECT_EQ(index.status, 200u);
  EXPECT_EQ(index.Header("Content-Type"), "text/html; charset=utf-8");
  EXPECT_NE(index.body.find("<title>Reconduit</title>"), std::string::npos);

  TestResponse unknown = Fetch(port, "GET", "/api/v1/nope");
  EXPECT_EQ(unknown.status, 404u);
  EXPECT_EQ(Json(unknown)["error"]["code"], "not_found");
  EXPECT_EQ(Fetch(port, "POST", "/api/v1/nope").status, 404u);

  TestResponse wrong_verb = Fetch(port, "POST", "/healthz");
  EXPECT_EQ(wrong_verb.status, 405u);
  EXPECT_EQ(wrong_verb.Header("Allow"), "GET, HEAD");
  EXPECT_EQ(Json(wrong_verb)["error"]["code"], "method_not_allowed");

  for (const char* attack : {"/../secret.txt", "/%2e%2e/secret.txt", "/..%2fsecret.txt",
                             "/%2E%2E%2Fsecret.txt", "//secret.txt", "/web/../../secret.txt"}) {
    SCOPED_TRACE(attack);
    TestResponse response = Fetch(port, "GET", attack);
    EXPECT_TRUE(response.status == 400u || response.status == 404u) << response.status;
    EXPECT_EQ(response.body.find("top secret"), std::string::npos);
    EXPECT_TRUE(Json(response).contains("error"));
  }

  // Content-Length over the limit: 413 without sending a byte of the body.
  TestClient big(port);
  ASSERT_TRUE(
      big.Write("POST /api/v1/jobs HTTP/1.1\r\nHost: x\r\n"
                "Content-Type: multipart/form-data; boundary=b\r\n"
                "Content-Length: 1000000000\r\n\r\n"));
  TestResponse too_large = big.Read();
  EXPECT_EQ(too_large.status, 413u) << too_large.error;
  EXPECT_EQ(Json(too_large)["error"]["code"], "payload_too_large");

  // SIGTERM with an idle keep-alive connection open: prompt exit 0.
  TestClient idle(port);
  ASSERT_EQ(idle.Request("GET", "/healthz").status, 200u);
  const auto start = std::chrono::steady_clock::now();
  server.Signal(SIGTERM);
  EXPECT_EQ(server.WaitForExit(5s), 0) << server.Stderr();
  EXPECT_LT(std::chrono::steady_clock::now() - start, 3s);
  EXPECT_NE(server.Stderr().find("GET /healthz 200"), std::string::npos) << server.Stderr();
}

TEST_F(HttpServerTest, EnforcesTheBearerToken) {
  ServerProcess server;
  std::vector<std::string> args = BaseArgs();
  args.insert(args.end(), {"--token", "s3cret-token"});
  ASSERT_TRUE(server.Start(args, dir_ / "stderr.txt")) << server.error();
  ASSERT_TRUE(server.WaitUntilHealthy()) << server.Stderr();
  const int port = server.port();

  EXPECT_EQ(Fetch(port, "GET", "/healthz").status, 200u);
  TestResponse missing = Fetch(port, "GET", "/");
  EXPECT_EQ(missing.status, 401u);
  EXPECT_EQ(missing.Header("WWW-Authenticate").rfind("Bearer", 0), 0u);
  EXPECT_EQ(Json(missing)["error"]["code"], "unauthorized");
  EXPECT_EQ(Fetch(port, "GET", "/", {{"Authorization", "Bearer s3cret-tokeN"}}).status, 401u);
  EXPECT_EQ(Fetch(port, "GET", "/", {{"Authorization", "Bearer s3cret"}}).status, 401u);
  EXPECT_EQ(Fetch(port, "GET", "/", {{"Authorization", "Bearer s3cret-token"}}).status, 200u);

  server.Signal(SIGINT);
  EXPECT_EQ(server.WaitForExit(5s), 0);
}

TEST_F(HttpServerTest, TakenPortIsAClearStartupError) {
  ServerProcess first;
  ASSERT_TRUE(first.Start(BaseArgs(), dir_ / "stderr1.txt")) << first.error();
  std::vector<std::string> args = BaseArgs();
  args[3] = std::to_string(first.port());
  ServerProcess second;
  EXPECT_FALSE(second.Start(args, dir_ / "stderr2.txt"));
  EXPECT_EQ(second.WaitForExit(5s), 1);
  EXPECT_NE(second.Stderr().find("cannot listen on 127.0.0.1:" + std::to_string(first.port())),
            std::string::npos)
      << second.Stderr();
  first.Signal(SIGTERM);
  EXPECT_EQ(first.WaitForExit(5s), 0);
}

TEST_F(HttpServerTest, MissingWebFolderIsAWarningNotACrash) {
  ServerProcess server;
  std::vector<std::string> args = BaseArgs();
  args[7] = (dir_ / "no-such-web").string();
  ASSERT_TRUE(server.Start(args, dir_ / "stderr.txt")) << server.error();
  ASSERT_TRUE(server.WaitUntilHealthy());
  TestResponse index = Fetch(server.port(), "GET", "/");
  EXPECT_EQ(index.status, 404u);
  EXPECT_EQ(Json(index)["error"]["code"], "not_found");
  EXPECT_NE(server.Stderr().find("does not exist"), std::string::npos) << server.Stderr();
  server.Signal(SIGTERM);
  EXPECT_EQ(server.WaitForExit(5s), 0);
}

TEST_F(HttpServerTest, BadFlagsExitWithUsageError) {
  ServerProcess server;
  EXPECT_FALSE(server.Start({"--threads", "0", "--port", "0"}, dir_ / "stderr.txt"));
  EXPECT_EQ(server.WaitForExit(5s), 2);
  EXPECT_NE(server.Stderr().find("num_threads"), std::string::npos) << server.Stderr();
}

}  // namespace
}  // namespace reconduit::server
