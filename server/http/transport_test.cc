// Drives a real HttpServer on a loopback port: keep-alive, limits, timeouts, streaming bodies,
// the exception boundary, the connection cap and graceful shutdown.
#include "server/http/multipart.h"
#include "server/http/server.h"
#include "server/http/test_client.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace reconduit::server {
namespace {

using namespace std::chrono_literals;

// Counts multipart parts and bytes of a streamed upload.
class CountingSink : public BodySink {
 public:
  CountingSink(std::string boundary, std::atomic<int>* aborts)
      : aborts_(aborts),
        parser_(std::move(boundary),
                {.on_part_begin =
                     [this](const MultipartPart& part) {
                       names_.push_back(part.name);
                       return Status::Ok();
                     },
                 .on_part_data =
                     [this](std::string_view data) {
                       bytes_ += data.size();
                       return Status::Ok();
                     },
                 .on_part_end = [] { return Status::Ok(); }}) {}

  std::optional<Response> OnData(std::string_view chunk) override {
    ++pieces_;
    if (Status status = parser_.Feed(chunk); !status.ok()) return ResponseFromStatus(status);
    return std::nullopt;
  }
  Response OnComplete(RequestContext&) override {
    if (Status status = parser_.Finish(); !status.ok()) return ResponseFromStatus(status);
    return Response::Json({{"parts", names_}, {"bytes", bytes_}, {"pieces", pieces_}},
                          HttpStatus::created);
  }
  void OnAbort(std::string_view) override { ++*aborts_; }

 private:
  std::atomic<int>* aborts_;
  MultipartParser parser_;
  std::vector<std::string> names_;
  std::size_t bytes_ = 0;
  int pieces_ = 0;
};

// A gate a sink waits at until the test opens it: holds an upload mid-finalisation.
class Gate {
 public:
  // Called by the sink: says it arrived, then waits until Open().
  void Pass() {
    std::unique_lock<std::mutex> lock(mutex_);
    arrived_ = true;
    changed_.notify_all();
    changed_.wait(lock, [this] { return open_; });
  }
  // Called by the test: true once a sink waits at the gate (within `timeout`).
  bool WaitForArrival(std::chrono::milliseconds timeout) {
    std::unique_lock<std::mutex> lock(mutex_);
    return changed_.wait_for(lock, timeout, [this] { return arrived_; });
  }
  void Open() {
    std::lock_guard<std::mutex> lock(mutex_);
    open_ = true;
    changed_.notify_all();
  }

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  bool arrived_ = false;
  bool open_ = false;
};

// Stands for an upload whose storing blocks (disk writes, zip extraction, fsync): waits at the
// gate in OnData (?hold=data) or in OnComplete (otherwise).
class GatedSink : public BodySink {
 public:
  GatedSink(Gate* gate, bool hold_data) : gate_(gate), hold_data_(hold_data) {}
  std::optional<Response> OnData(std::string_view chunk) override {
    if (hold_data_ && bytes_ == 0) gate_->Pass();
    bytes_ += chunk.size();
    return std::nullopt;
  }
  Response OnComplete(RequestContext&) override {
    if (!hold_data_) gate_->Pass();
    return Response::Json({{"bytes", bytes_}}, HttpStatus::created);
  }

 private:
  Gate* gate_;
  bool hold_data_;
  std::size_t bytes_ = 0;
};

class TransportTest : public ::testing::Test {
 protected:
  void Start(HttpServerOptions options = {}) {
    options.host = "127.0.0.1";
    options.port = 0;
    options.handle_signals = false;
    options.num_threads = io_threads_;
    Router router;
    router.Add(HttpVerb::get, "/healthz", [](RequestContext&) {
      return Response::Json({{"status", "ok"}});
    });
    router.Add(HttpVerb::post, "/echo", [](RequestContext& context) {
      return Response::Json({{"body", context.body},
                             {"query", context.query},
                             {"remote", context.remote_address},
                             {"id", context.request_id}});
    });
    router.Add(HttpVerb::get, "/items/{id}", [](RequestContext& context) {
      return Response::Text("item " + std::string(context.PathParam("id")));
    });
    router.Add(HttpVerb::get, "/throw",
               [](RequestContext&) -> Response { throw std::runtime_error("boom /secret/path"); });
    router.Add(HttpVerb::get, "/slow", [](RequestContext&) {
      std::this_thread::sleep_for(400ms);
      return Response::Text("slow done");
    });
    router.AddStreaming(HttpVerb::post, "/upload", [this](RequestContext& context) -> StreamStart {
      Result<std::string> boundary = MultipartBoundary(context.Header("Content-Type").value_or(""));
      if (!boundary.ok()) {
        return ErrorResponse(HttpStatus::unsupported_media_type, boundary.status().message());
      }
      return std::make_unique<CountingSink>(*boundary, &aborts_);
    });
    router.AddBlocking(HttpVerb::post, "/held", [this](RequestContext&) {
      gate_.Pass();
      return Response::Text("released");
    });
    router.AddStreaming(HttpVerb::post, "/gated", [this](RequestContext& context) -> StreamStart {
      return std::make_unique<GatedSink>(&gate_, context.Query("hold") == "data");
    });
    server_ = std::make_unique<HttpServer>(options, std::move(router));
    ASSERT_TRUE(server_->Listen().ok());
    port_ = server_->port();
    ASSERT_GT(port_, 0);
    thread_ = std::thread([this] { run_status_ = server_->Run(); });
  }

  void TearDown() override { Stop(); }

  void Stop() {
    if (!thread_.joinable()) return;
    server_->Shutdown();
    thread_.join();
  }

  static std::string MultipartBody(std::size_t image_bytes) {
    return "--XyZ\r\nContent-Disposition: form-data; name=\"options\"\r\n\r\n{}\r\n"
           "--XyZ\r\nContent-Disposition: form-data; name=\"images\"; filename=\"a.jpg\"\r\n"
           "Content-Type: image/jpeg\r\n\r\n" +
           std::string(image_bytes, 'J') + "\r\n--XyZ--\r\n";
  }

  std::unique_ptr<HttpServer> server_;
  std::thread thread_;
  Status run_status_;
  int port_ = 0;
  int io_threads_ = 2;
  std::atomic<int> aborts_{0};
  Gate gate_;
};

TEST_F(TransportTest, EveryResponseCarriesTheCommonHeaders) {
  Start();
  TestResponse response = Fetch(port_, "GET", "/healthz");
  ASSERT_EQ(response.status, 200u) << response.error;
  EXPECT_EQ(nlohmann::json::parse(response.body), (nlohmann::json{{"status", "ok"}}));
  EXPECT_EQ(response.Header("Server"), "reconduit");
  EXPECT_EQ(response.Header("Content-Type"), "application/json");
  EXPECT_EQ(response.Header("X-Request-Id").size(), 16u);

  response = Fetch(port_, "GET", "/nope", {{"X-Request-Id", "abc-123"}});
  EXPECT_EQ(response.status, 404u);
  EXPECT_EQ(response.Header("X-Request-Id"), "abc-123");
  EXPECT_EQ(nlohmann::json::parse(response.body)["error"]["code"], "not_found");

  // An unsafe client id is replaced.
  response = Fetch(port_, "GET", "/healthz", {{"X-Request-Id", "a b\"c"}});
  EXPECT_EQ(response.Header("X-Request-Id").size(), 16u);
}

TEST_F(TransportTest, KeepAliveServesSeveralRequestsOnOneConnection) {
  Start();
  TestClient client(port_);
  ASSERT_TRUE(client.connected());
  for (int i = 0; i < 3; ++i) {
    TestResponse response =
        client.Request("POST", "/echo?a=1&b=x%20y", {}, "hello " + std::to_string(i));
    ASSERT_EQ(response.status, 200u) << response.error;
    const nlohmann::json body = nlohmann::json::parse(response.body);
    EXPECT_EQ(body["body"], "hello " + std::to_string(i));
    EXPECT_EQ(body["query"][1][1], "x y");
    EXPECT_EQ(body["remote"], "127.0.0.1");
  }
  TestResponse item = client.Request("GET", "/items/a%2Fb");
  EXPECT_EQ(item.body, "item a/b");
  EXPECT_EQ(client.Request("PUT", "/items/1").Header("Allow"), "GET, HEAD");
}

TEST_F(TransportTest, HeadHasLengthButNoBody) {
  Start();
  TestClient client(port_);
  ASSERT_TRUE(client.Write("HEAD /items/7 HTTP/1.1\r\nHost: x\r\n\r\n"));
  TestResponse head = client.Read(/*head_response=*/true);
  EXPECT_EQ(head.status, 200u) << head.error;
  EXPECT_EQ(head.Header("Content-Length"), "6");  // "item 7"
  EXPECT_EQ(head.body, "");
  // Had the server sent a body, this response would be misparsed.
  TestResponse next = client.Request("GET", "/items/8");
  EXPECT_EQ(next.status, 200u) << next.error;
  EXPECT_EQ(next.body, "item 8");
}

TEST_F(TransportTest, HandlerExceptionBecomesA500AndTheServerLives) {
  Start();
  TestResponse response = Fetch(port_, "GET", "/throw");
  EXPECT_EQ(response.status, 500u);
  const nlohmann::json body = nlohmann::json::parse(response.body);
  EXPECT_EQ(body["error"]["code"], "internal");
  EXPECT_EQ(response.body.find("/secret/path"), std::string::npos);
  EXPECT_EQ(Fetch(port_, "GET", "/healthz").status, 200u);
}

TEST_F(TransportTest, MalformedRequestsGet400) {
  Start();
  TestClient client(port_);
  ASSERT_TRUE(client.Write("GARBAGE\r\n\r\n"));
  EXPECT_EQ(client.Read().status, 400u);
  EXPECT_EQ(Fetch(port_, "GET", "/echo?x=%zz").status, 400u);
  EXPECT_EQ(Fetch(port_, "GET", "http://example.com/healthz").status, 400u);
}

TEST_F(TransportTest, OversizedHeaderGets431) {
  HttpServerOptions options;
  options.max_header_bytes = 2048;
  Start(options);
  TestResponse response = Fetch(port_, "GET", "/healthz", {{"X-Big", std::string(4096, 'h')}});
  EXPECT_EQ(response.status, 431u);
  EXPECT_EQ(nlohmann::json::parse(response.body)["error"]["code"], "header_too_large");
}

TEST_F(TransportTest, BufferedBodyOverLimitGets413) {
  HttpServerOptions options;
  options.max_body_bytes = 100;
  Start(options);
  EXPECT_EQ(Fetch(port_, "POST", "/echo", {}, std::string(100, 'a')).status, 200u);
  EXPECT_EQ(Fetch(port_, "POST", "/echo", {}, std::string(101, 'a')).status, 413u);
  // Chunked: the size is only known while reading.
  TestClient client(port_);
  ASSERT_TRUE(
      client.Write("POST /echo HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\n"
                   "50\r\n" +
                   std::string(80, 'a') + "\r\n50\r\n" + std::string(80, 'b') + "\r\n0\r\n\r\n"));
  TestResponse response = client.Read();
  EXPECT_EQ(response.status, 413u);
  EXPECT_EQ(response.Header("Connection"), "close");
}

TEST_F(TransportTest, StreamsAMultipartUpload) {
  Start();
  const std::string body = MultipartBody(1000000);
  TestResponse response = Fetch(port_, "POST", "/upload",
                                {{"Content-Type", "multipart/form-data; boundary=XyZ"}}, body);
  ASSERT_EQ(response.status, 201u) << response.body << response.error;
  const nlohmann::json json = nlohmann::json::parse(response.body);
  EXPECT_EQ(json["parts"], (nlohmann::json{"options", "images"}));
  EXPECT_EQ(json["bytes"], 1000002);
  // Delivered in pieces, not as one buffer.
  EXPECT_GT(json["pieces"].get<int>(), 10);
}

TEST_F(TransportTest, StreamsAChunkedUploadWithExpectContinue) {
  Start();
  const std::string body = MultipartBody(5000);
  TestClient client(port_);
  ASSERT_TRUE(
      client.Write("POST /upload HTTP/1.1\r\nHost: x\r\n"
                   "Content-Type: multipart/form-data; boundary=XyZ\r\n"
                   "Transfer-Encoding: chunked\r\nExpect: 100-continue\r\n\r\n"));
  TestResponse interim = client.Read();
  ASSERT_EQ(interim.status, 100u) << interim.error;
  std::string chunked;
  for (std::size_t i = 0; i < body.size(); i += 999) {
    const std::string piece = body.substr(i, 999);
    char size[16];
    std::snprintf(size, sizeof(size), "%zx\r\n", piece.size());
    chunked += size + piece + "\r\n";
  }
  chunked += "0\r\n\r\n";
  ASSERT_TRUE(client.Write(chunked));
  TestResponse response = client.Read();
  ASSERT_EQ(response.status, 201u) << response.body;
  EXPECT_EQ(nlohmann::json::parse(response.body)["bytes"], 5002);
}

TEST_F(TransportTest, StreamingRouteCanRefuseBeforeTheBody) {
  Start();
  TestResponse response = Fetch(port_, "POST", "/upload", {{"Content-Type", "image/jpeg"}}, "x");
  EXPECT_EQ(response.status, 415u);
  EXPECT_EQ(nlohmann::json::parse(response.body)["error"]["code"], "unsupported_media_type");
}

TEST_F(TransportTest, SinkErrorEndsTheRequest) {
  Start();
  TestResponse response =
      Fetch(port_, "POST", "/upload", {{"Content-Type", "multipart/form-data; boundary=XyZ"}},
            "--XyZ\r\nno colon\r\n\r\nx\r\n--XyZ--");
  EXPECT_EQ(response.status, 400u);
  EXPECT_EQ(nlohmann::json::parse(response.body)["error"]["code"], "bad_request");
  // Truncated multipart: the body ends before the closing boundary.
  response =
      Fetch(port_, "POST", "/upload", {{"Content-Type", "multipart/form-data; boundary=XyZ"}},
            MultipartBody(10).substr(0, 100));
  EXPECT_EQ(response.status, 400u);
}

TEST_F(TransportTest, UploadOverLimitGets413BeforeTheBody) {
  HttpServerOptions options;
  options.max_upload_bytes = 1000;
  Start(options);
  TestClient client(port_);
  // Expect: 100-continue, so a conforming server must answer without reading the body.
  ASSERT_TRUE(
      client.Write("POST /upload HTTP/1.1\r\nHost: x\r\n"
                   "Content-Type: multipart/form-data; boundary=XyZ\r\n"
                   "Content-Length: 1000000000\r\nExpect: 100-continue\r\n\r\n"));
  TestResponse response = client.Read();
  EXPECT_EQ(response.status, 413u);
  EXPECT_EQ(nlohmann::json::parse(response.body)["error"]["code"], "payload_too_large");
  EXPECT_TRUE(client.WaitForClose());
  EXPECT_EQ(aborts_.load(), 0);  // The handler never started.
}

TEST_F(TransportTest, StalledBodyTimesOutAndAbortsTheSink) {
  HttpServerOptions options;
  options.body_timeout = 300ms;
  Start(options);
  TestClient client(port_, 5s);
  ASSERT_TRUE(
      client.Write("POST /upload HTTP/1.1\r\nHost: x\r\n"
                   "Content-Type: multipart/form-data; boundary=XyZ\r\n"
                   "Content-Length: 100\r\n\r\n--XyZ\r\n"));
  const auto start = std::chrono::steady_clock::now();
  EXPECT_TRUE(client.WaitForClose());
  EXPECT_LT(std::chrono::steady_clock::now() - start, 3s);
  for (int i = 0; i < 100 && aborts_.load() == 0; ++i) std::this_thread::sleep_for(10ms);
  EXPECT_EQ(aborts_.load(), 1);
}

TEST_F(TransportTest, IncompleteHeaderTimesOut) {
  HttpServerOptions options;
  options.header_timeout = 300ms;
  Start(options);
  TestClient client(port_, 5s);
  ASSERT_TRUE(client.Write("GET /healthz HTTP/1.1\r\nHost:"));
  const auto start = std::chrono::steady_clock::now();
  EXPECT_TRUE(client.WaitForClose());
  EXPECT_LT(std::chrono::steady_clock::now() - start, 3s);
}

TEST_F(TransportTest, ConnectionsOverTheCapGet503) {
  HttpServerOptions options;
  options.max_connections = 2;
  options.retry_after_seconds = 3;
  Start(options);
  TestClient first(port_);
  TestClient second(port_);
  ASSERT_EQ(first.Request("GET", "/healthz").status, 200u);
  ASSERT_EQ(second.Request("GET", "/healthz").status, 200u);
  TestClient third(port_);
  TestResponse response = third.Read();
  EXPECT_EQ(response.status, 503u) << response.error;
  EXPECT_EQ(response.Header("Retry-After"), "3");
  EXPECT_EQ(nlohmann::json::parse(response.body)["error"]["code"], "unavailable");
}

TEST_F(TransportTest, BearerTokenProtectsAllButPublicPaths) {
  HttpServerOptions options;
  options.bearer_token = "s3cret";
  Start(options);
  EXPECT_EQ(Fetch(port_, "GET", "/healthz").status, 200u);
  TestResponse response = Fetch(port_, "GET", "/items/1");
  EXPECT_EQ(response.status, 401u);
  EXPECT_EQ(response.Header("WWW-Authenticate").rfind("Bearer", 0), 0u);
  EXPECT_EQ(Fetch(port_, "GET", "/items/1", {{"Authorization", "Bearer wrong"}}).status, 401u);
  EXPECT_EQ(Fetch(port_, "GET", "/items/1", {{"Authorization", "Basic czNjcmV0"}}).status, 401u);
  EXPECT_EQ(Fetch(port_, "GET", "/items/1", {{"Authorization", "Bearer s3cret"}}).status, 200u);
  EXPECT_EQ(Fetch(port_, "GET", "/items/1", {{"Authorization", "bearer s3cret"}}).status, 200u);
  // Unknown paths do not reveal themselves without the token.
  EXPECT_EQ(Fetch(port_, "GET", "/nope").status, 401u);
}

TEST_F(TransportTest, ShutdownClosesIdleConnectionsAndFinishesInFlightRequests) {
  HttpServerOptions options;
  options.shutdown_grace = 5s;
  Start(options);
  TestClient idle(port_);
  ASSERT_EQ(idle.Request("GET", "/healthz").status, 200u);

  TestClient busy(port_);
  ASSERT_TRUE(busy.Write("GET /slow HTTP/1.1\r\nHost: x\r\n\r\n"));
  std::this_thread::sleep_for(100ms);  // Let the handler start.
  const auto start = std::chrono::steady_clock::now();
  server_->Shutdown();

  TestResponse response = busy.Read();
  EXPECT_EQ(response.status, 200u) << response.error;
  EXPECT_EQ(response.body, "slow done");
  EXPECT_EQ(response.Header("Connection"), "close");
  EXPECT_TRUE(idle.WaitForClose());
  thread_.join();
  EXPECT_TRUE(run_status_.ok());
  EXPECT_LT(std::chrono::steady_clock::now() - start, 3s);
  // No longer accepting.
  EXPECT_FALSE(TestClient(port_).Request("GET", "/healthz").status == 200u);
}

TEST_F(TransportTest, GracePeriodBoundsShutdown) {
  HttpServerOptions options;
  options.shutdown_grace = 200ms;
  options.body_timeout = 30s;
  Start(options);
  TestClient stalled(port_, 5s);
  ASSERT_TRUE(
      stalled.Write("POST /upload HTTP/1.1\r\nHost: x\r\n"
                    "Content-Type: multipart/form-data; boundary=XyZ\r\n"
                    "Content-Length: 100\r\n\r\n--XyZ"));
  std::this_thread::sleep_for(100ms);
  const auto start = std::chrono::steady_clock::now();
  server_->Shutdown();
  thread_.join();
  EXPECT_LT(std::chrono::steady_clock::now() - start, 2s);
  EXPECT_TRUE(stalled.WaitForClose());
}

TEST(HttpServerOptions, DefaultsAreValidAndBadValuesNamed) {
  std::string error;
  EXPECT_TRUE(HttpServerOptions().Check(&error)) << error;
  HttpServerOptions options;
  options.num_threads = 0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("num_threads"), std::string::npos);
  options = HttpServerOptions();
  options.port = 70000;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("port"), std::string::npos);
  options = HttpServerOptions();
  options.bearer_token = "has space";
  EXPECT_FALSE(options.Check(&error));
  EXPECT_THROW(HttpServer(options, Router()), CheckError);
}

TEST(HttpServer, ListenFailsClearlyWhenThePortIsTaken) {
  HttpServerOptions options;
  options.port = 0;
  options.handle_signals = false;
  HttpServer first(options, Router());
  ASSERT_TRUE(first.Listen().ok());
  options.port = first.port();
  HttpServer second(options, Router());
  const Status status = second.Listen();
  EXPECT_EQ(status.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(status.message().find("cannot listen on 127.0.0.1:" + std::to_string(first.port())),
            std::string::npos)
      << status;
  EXPECT_NE(status.message().find("in use"), std::string::npos) << status;
}

}  // namespace
}  // namespace reconduit::server

namespace reconduit::server {
namespace {

// With one I/O thread, /healthz is answered while an upload's sink is blocked in OnComplete
// (or in OnData): the sinks run on the blocking pool, not on the I/O threads.
void ExpectHealthzWhileGated(int port, Gate& gate, const std::string& target) {
  TestResponse upload;
  std::thread uploader([&] {
    TestClient client(port, std::chrono::seconds(30));
    upload = client.Request("POST", target, {{"Content-Type", "application/octet-stream"}},
                            std::string(200 * 1024, 'z'));
  });
  ASSERT_TRUE(gate.WaitForArrival(std::chrono::seconds(10)));
  // Held: the I/O thread must still serve others. (Before the pool, this request waited
  // until the gate opened, and its client gave up after 10 s.)
  TestResponse health = Fetch(port, "GET", "/healthz");
  TestResponse again = Fetch(port, "GET", "/items/7");
  gate.Open();
  uploader.join();
  EXPECT_EQ(health.status, 200u) << health.error;
  EXPECT_EQ(again.status, 200u) << again.error;
  ASSERT_EQ(upload.status, 201u) << upload.error;
  EXPECT_EQ(nlohmann::json::parse(upload.body)["bytes"], 200 * 1024);
}

TEST_F(TransportTest, HealthzAnswersWhileAnUploadIsFinalising) {
  io_threads_ = 1;
  Start();
  ExpectHealthzWhileGated(port_, gate_, "/gated");
}

TEST_F(TransportTest, HealthzAnswersWhileAnUploadIsStoringABodyPiece) {
  io_threads_ = 1;
  Start();
  ExpectHealthzWhileGated(port_, gate_, "/gated?hold=data");
}

// A handler added with AddBlocking (a store write waiting for another process's lock, a folder
// being removed) holds a thread of the blocking pool, not the only I/O thread.
TEST_F(TransportTest, HealthzAnswersWhileABlockingHandlerWaits) {
  io_threads_ = 1;
  Start();
  TestResponse held;
  std::thread client([&] { held = Fetch(port_, "POST", "/held"); });
  ASSERT_TRUE(gate_.WaitForArrival(std::chrono::seconds(10)));
  const auto start = std::chrono::steady_clock::now();
  const TestResponse health = Fetch(port_, "GET", "/healthz");
  const auto waited = std::chrono::steady_clock::now() - start;
  gate_.Open();
  client.join();
  EXPECT_EQ(health.status, 200u) << health.error;
  EXPECT_LT(waited, std::chrono::seconds(2));
  EXPECT_EQ(held.status, 200u) << held.error;
  EXPECT_EQ(held.body, "released");
}

TEST_F(TransportTest, OneAddressCannotTakeEveryConnection) {
  HttpServerOptions options;
  options.max_connections = 8;
  options.max_connections_per_address = 2;
  options.retry_after_seconds = 4;
  Start(options);
  TestClient first(port_);
  TestClient second(port_);
  ASSERT_EQ(first.Request("GET", "/items/1").status, 200u);
  ASSERT_EQ(second.Request("GET", "/items/2").status, 200u);

  // A third connection from the same address is refused...
  TestClient third(port_);
  TestResponse refused = third.Request("GET", "/items/3");
  EXPECT_EQ(refused.status, 503u) << refused.error;
  EXPECT_EQ(refused.Header("Retry-After"), "4");
  // ...but may still ask for /healthz...
  TestClient probe(port_);
  TestResponse health = probe.Request("GET", "/healthz");
  EXPECT_EQ(health.status, 200u) << health.error;
  EXPECT_EQ(health.Header("Connection"), "close");
  // ...and another address is served normally.
  TestClient other(port_, std::chrono::seconds(10), "127.0.0.2");
  ASSERT_TRUE(other.connected());
  TestResponse served = other.Request("GET", "/items/4");
  EXPECT_EQ(served.status, 200u) << served.error;
  EXPECT_EQ(served.body, "item 4");

  // The address's places come back when its connections close.
  first.Request("GET", "/items/1", {{"Connection", "close"}});
  EXPECT_TRUE(first.WaitForClose());
  for (int attempt = 0; attempt < 100 && server_->ConnectionCount() > 2; ++attempt) {
    std::this_thread::sleep_for(10ms);
  }
  TestClient again(port_);
  EXPECT_EQ(again.Request("GET", "/items/5").status, 200u);
}

// Issue 12's done-when: 300 slow connections from one address (one header byte each, never
// finished) leave another address served normally, with the default limits.
TEST_F(TransportTest, ThreeHundredSlowConnectionsFromOneAddressLeaveOthersServed) {
  Start(HttpServerOptions());
  std::vector<std::unique_ptr<TestClient>> slow;
  for (int i = 0; i < 300; ++i) {
    slow.push_back(std::make_unique<TestClient>(port_, std::chrono::seconds(10)));
    if (slow.back()->connected()) slow.back()->Write("G");
  }
  for (int k = 0; k < 5; ++k) {
    TestClient other(port_, std::chrono::seconds(10), "127.0.0.2");
    ASSERT_TRUE(other.connected());
    const auto start = std::chrono::steady_clock::now();
    TestResponse served = other.Request("GET", "/items/" + std::to_string(k));
    EXPECT_EQ(served.status, 200u) << served.error;
    EXPECT_EQ(served.body, "item " + std::to_string(k));
    EXPECT_LT(std::chrono::steady_clock::now() - start, 1s);
  }
}

// Issue 12: "gzip, chunked" was read as chunked with the gzip coding ignored.
TEST_F(TransportTest, TransferCodingsOtherThanChunkedGet501) {
  Start();
  for (const char* coding : {"gzip, chunked", "deflate", "gzip"}) {
    TestClient client(port_);
    ASSERT_TRUE(client.Write(std::string("POST /echo HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: ") +
                             coding + "\r\n\r\n5\r\nhello\r\n0\r\n\r\n"));
    const TestResponse response = client.Read();
    EXPECT_EQ(response.status, 501u) << coding << " " << response.error << " " << response.body;
    EXPECT_EQ(response.Header("X-Content-Type-Options"), "nosniff");
  }
  TestClient client(port_);
  ASSERT_TRUE(
      client.Write("POST /echo HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: "
                   "Chunked\r\n\r\n5\r\nhello\r\n0\r\n\r\n"));
  const TestResponse plain = client.Read();
  ASSERT_EQ(plain.status, 200u) << plain.error;
  EXPECT_EQ(nlohmann::json::parse(plain.body)["body"], "hello");
  EXPECT_EQ(plain.Header("X-Content-Type-Options"), "nosniff");
}

TEST(HttpServerOptionsTest, ChecksTheNewLimits) {
  HttpServerOptions options;
  std::string error;
  EXPECT_TRUE(options.Check(&error)) << error;
  options.max_connections_per_address = 0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("max_connections_per_address"), std::string::npos);
  options.max_connections_per_address = 1;
  options.blocking_threads = 0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("blocking_threads"), std::string::npos);
}

}  // namespace
}  // namespace reconduit::server
