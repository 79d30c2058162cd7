// Integration test of the reconduit-server binary: starts it as a child process on a free port
// with a temporary data folder and checks its behaviour over real sockets.
#include "server/http/test_client.h"
#include "tests/server_process.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <arpa/inet.h>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sstream>
#include <string>
#include <sys/socket.h>
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

// A TCP port that was free a moment ago (bound to port 0, read back, closed).
int FreePort() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t length = sizeof(address);
  if (fd < 0 || ::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)) != 0 ||
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) != 0) {
    if (fd >= 0) ::close(fd);
    return -1;
  }
  ::close(fd);
  return ntohs(address.sin_port);
}

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
  TestResponse missing = Fetch(port, "GET", "/api/v1/jobs");
  EXPECT_EQ(missing.status, 401u);
  EXPECT_EQ(missing.Header("WWW-Authenticate").rfind("Bearer", 0), 0u);
  EXPECT_EQ(Json(missing)["error"]["code"], "unauthorized");
  EXPECT_EQ(Fetch(port, "GET", "/api/v1/jobs", {{"Authorization", "Bearer s3cret-tokeN"}}).status,
            401u);
  EXPECT_EQ(Fetch(port, "GET", "/api/v1/jobs", {{"Authorization", "Bearer s3cret"}}).status, 401u);
  EXPECT_EQ(Fetch(port, "GET", "/api/v1/jobs", {{"Authorization", "Bearer s3cret-token"}}).status,
            200u);
  // The page's own files are public (a browser cannot send the header when it loads them; the
  // page then asks for the token and sends it on every API call).
  EXPECT_EQ(Fetch(port, "GET", "/").status, 200u);

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

TEST_F(HttpServerTest, ConfigFileSetsOptionsUnderTheEnvironmentAndFlags) {
  const int file_port = FreePort();
  ASSERT_GT(file_port, 0);
  const fs::path config = dir_ / "server.conf";
  std::ofstream(config) << "# reconduit-server settings\n"
                        << "host = 127.0.0.1\n"
                        << "port = " << file_port << "\n"
                        << "data = " << (dir_ / "data").string() << "\n"
                        << "web = " << (dir_ / "web").string() << "\n"
                        << "threads = 2   # trailing comment\n"
                        << "token = file-token\n"
                        << "max-upload-bytes = 1000\n";
  auto status_with = [](int port, const std::string& token) {
    return Fetch(port, "GET", "/api/v1/jobs", {{"Authorization", "Bearer " + token}}).status;
  };
  // A 2000-byte upload (not a valid form): 413 when over the upload limit, 400 otherwise.
  auto upload_status = [](int port, const std::string& token) {
    TestClient client(port);
    if (!client.Write("POST /api/v1/jobs HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer " + token +
                      "\r\nContent-Type: multipart/form-data; boundary=b\r\n"
                      "Content-Length: 2000\r\n\r\n" +
                      std::string(2000, 'x'))) {
      return 0u;
    }
    return client.Read().status;
  };
  {
    // The file alone: its port, token and upload limit apply.
    ServerProcess server;
    ASSERT_TRUE(server.Start({"--config", config.string()}, dir_ / "stderr1.txt"))
        << server.error();
    ASSERT_TRUE(server.WaitUntilHealthy()) << server.Stderr();
    EXPECT_EQ(server.port(), file_port);
    EXPECT_EQ(Fetch(server.port(), "GET", "/api/v1/jobs").status, 401u);
    EXPECT_EQ(status_with(server.port(), "file-token"), 200u);
    EXPECT_EQ(upload_status(server.port(), "file-token"), 413u);
    EXPECT_EQ(server.Terminate(5s), 0) << server.Stderr();
  }
  {
    // RECONDUIT_CONFIG names the file; the environment wins over it, flags win over both.
    ServerProcess server;
    ASSERT_TRUE(server.Start({"--port", "0", "--token", "flag-token"}, dir_ / "stderr2.txt",
                             {"RECONDUIT_CONFIG=" + config.string(), "RECONDUIT_TOKEN=env-token",
                              "RECONDUIT_MAX_UPLOAD_BYTES=100000"}))
        << server.error();
    ASSERT_TRUE(server.WaitUntilHealthy()) << server.Stderr();
    EXPECT_NE(server.port(), file_port);
    EXPECT_EQ(status_with(server.port(), "flag-token"), 200u);
    EXPECT_EQ(status_with(server.port(), "env-token"), 401u);
    EXPECT_EQ(status_with(server.port(), "file-token"), 401u);
    // 2000 bytes are under the environment's limit.
    EXPECT_EQ(upload_status(server.port(), "flag-token"), 400u);
    EXPECT_EQ(server.Terminate(5s), 0) << server.Stderr();
  }
  {
    ServerProcess server;
    ASSERT_TRUE(server.Start({"--config", config.string(), "--port", "0"}, dir_ / "stderr3.txt",
                             {"RECONDUIT_TOKEN=env-token"}))
        << server.error();
    ASSERT_TRUE(server.WaitUntilHealthy()) << server.Stderr();
    EXPECT_EQ(status_with(server.port(), "env-token"), 200u);
    EXPECT_EQ(status_with(server.port(), "file-token"), 401u);
    EXPECT_EQ(upload_status(server.port(), "env-token"), 413u);
    EXPECT_EQ(server.Terminate(5s), 0) << server.Stderr();
  }
}

// One file for both programs (as scripts/start.sh uses it through RECONDUIT_CONFIG): the shared
// data folder at the top, each program's settings in its section; each skips the other's.
TEST_F(HttpServerTest, ServerAndWorkerShareOneConfigFile) {
  const fs::path config = dir_ / "reconduit.conf";
  std::ofstream(config) << "# reconduit-server and reconduit-worker\n"
                        << "data = " << (dir_ / "shared-data").string() << "\n"
                        << "[server]\n"
                        << "host = 127.0.0.1\n"
                        << "port = 0\n"
                        << "threads = 2\n"
                        << "token = file-token\n"
                        << "[worker]\n"
                        << "id = shared-worker\n"
                        << "threads = 1\n"
                        << "lease = 2.5\n"
                        << "poll = 0.1\n"
                        << "once = true\n";
  ServerProcess server;
  ASSERT_TRUE(server.Start({}, dir_ / "stderr.txt", {"RECONDUIT_CONFIG=" + config.string()}))
      << server.error();
  ASSERT_TRUE(server.WaitUntilHealthy()) << server.Stderr();
  EXPECT_EQ(Fetch(server.port(), "GET", "/api/v1/jobs").status, 401u);
  EXPECT_EQ(
      Fetch(server.port(), "GET", "/api/v1/jobs", {{"Authorization", "Bearer file-token"}}).status,
      200u);
  EXPECT_TRUE(fs::exists(dir_ / "shared-data" / "reconduit.db"));

  // The worker on the same file: the same data folder, its own id and lease; once = true lets
  // it exit after one look at the (empty) queue.
  const fs::path worker_log = dir_ / "worker.txt";
  const std::string command = "RECONDUIT_CONFIG='" + config.string() + "' '" +
                              RECONDUIT_WORKER_BINARY + "' > '" + worker_log.string() + "' 2>&1";
  const int status = std::system(command.c_str());
  std::ifstream log_file(worker_log);
  const std::string log((std::istreambuf_iterator<char>(log_file)),
                        std::istreambuf_iterator<char>());
  ASSERT_TRUE(WIFEXITED(status)) << log;
  EXPECT_EQ(WEXITSTATUS(status), 0) << log;
  EXPECT_NE(log.find("reconduit-worker shared-worker: data folder " +
                     fs::absolute(dir_ / "shared-data").string() + ", lease 2.5 s"),
            std::string::npos)
      << log;
  EXPECT_EQ(server.Terminate(5s), 0) << server.Stderr();
}

TEST_F(HttpServerTest, BadConfigFileExitsWithUsageErrorNamingFileAndKey) {
  struct Case {
    std::string text;
    std::vector<std::string> expected;  // In the error message, besides the file name.
  };
  const std::vector<Case> cases = {
      {"port = 0\ncolour = blue\n", {"unrecognised option 'colour'"}},
      {"port = not-a-port\n", {"'not-a-port'", "'port'"}},
      {"port = 0\nthreads = 0\n", {"num_threads must be in [1, 64]", "'threads' in "}},
      {"port = 0\nport = 1\n", {"'port' cannot be specified more than once"}},
      // The file may serve both programs: [server] is read, other known sections are skipped,
      // but a typo in a name or a section name is still an error.
      {"[server]\nport = 0\ncolour = blue\n", {"unrecognised option 'server.colour'"}},
      {"[sever]\nport = 0\n", {"unknown section [sever]"}},
      {"port = 0\n[server]\nport = 1\n", {"'port' cannot be specified more than once"}},
      {"[server]\nport = not-a-port\n", {"'not-a-port'", "'server.port' in "}},
      {"port = 0\nconfig = other.conf\n", {"unrecognised option 'config'"}},
      {"port 0\n", {"invalid line 'port 0'"}},
  };
  for (std::size_t i = 0; i < cases.size(); ++i) {
    SCOPED_TRACE(cases[i].text);
    const fs::path config = dir_ / ("bad" + std::to_string(i) + ".conf");
    std::ofstream(config) << cases[i].text;
    ServerProcess server;
    EXPECT_FALSE(server.Start({"--config", config.string(), "--data", (dir_ / "data").string()},
                              dir_ / ("stderr" + std::to_string(i) + ".txt")));
    EXPECT_EQ(server.WaitForExit(5s), 2);
    const std::string error = server.Stderr();
    EXPECT_NE(error.find(config.string()), std::string::npos) << error;
    for (const std::string& expected : cases[i].expected) {
      EXPECT_NE(error.find(expected), std::string::npos) << expected << " in " << error;
    }
  }
  // An unreadable file (missing here) is the same kind of error.
  ServerProcess server;
  const fs::path missing = dir_ / "missing.conf";
  EXPECT_FALSE(server.Start({"--port", "0"}, dir_ / "stderr-missing.txt",
                            {"RECONDUIT_CONFIG=" + missing.string()}));
  EXPECT_EQ(server.WaitForExit(5s), 2);
  EXPECT_NE(server.Stderr().find("cannot read the config file '" + missing.string() + "'"),
            std::string::npos)
      << server.Stderr();
}

}  // namespace
}  // namespace reconduit::server
