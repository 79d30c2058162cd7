// A minimal synchronous HTTP/1.1 client (Beast) for tests of the server: one TCP connection,
// requests written as raw bytes or built from parts, responses parsed by Beast. Every read is
// bounded by a receive timeout so a misbehaving server fails a test instead of hanging it.
// Test-only; errors are reported in TestResponse::error rather than thrown.
#ifndef RECONDUIT_SERVER_HTTP_TEST_CLIENT_H_
#define RECONDUIT_SERVER_HTTP_TEST_CLIENT_H_

#include <chrono>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace reconduit::server {

struct TestResponse {
  // 0 when no response could be read (see `error`).
  unsigned status = 0;
  std::vector<std::pair<std::string, std::string>> headers;
  std::string body;
  // Empty on success; otherwise why the response could not be read.
  std::string error;

  // The first header called `name` (case-insensitive), or "".
  std::string Header(std::string_view name) const;
};

class TestClient {
 public:
  // Connects to 127.0.0.1:port; connected() tells whether it worked. A non-empty
  // `source_address` (e.g. "127.0.0.2": every 127.x.y.z is the loopback on Linux) is bound as
  // the connection's local address, so a test can act as several clients.
  explicit TestClient(int port,
                      std::chrono::milliseconds timeout = std::chrono::seconds(10),
                      const std::string& source_address = "");
  ~TestClient();
  TestClient(const TestClient&) = delete;
  TestClient& operator=(const TestClient&) = delete;

  bool connected() const;
  // Sends bytes as they are; false on error.
  bool Write(std::string_view bytes);
  // Reads one response; `head_response` when it answers a HEAD request (no body follows).
  TestResponse Read(bool head_response = false);
  // Builds and sends a request (Host and Content-Length added), then reads the response.
  TestResponse Request(std::string_view method,
                       std::string_view target,
                       const std::vector<std::pair<std::string, std::string>>& headers = {},
                       std::string_view body = {});
  // True when the server closes the connection within the timeout (reads until EOF or error).
  bool WaitForClose();

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// One request on a fresh connection.
TestResponse Fetch(int port,
                   std::string_view method,
                   std::string_view target,
                   const std::vector<std::pair<std::string, std::string>>& headers = {},
                   std::string_view body = {});

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_HTTP_TEST_CLIENT_H_
