// The HTTP transport: listener, per-connection sessions, limits and graceful shutdown.
//
// HttpServer accepts TCP connections and serves HTTP/1.1 on them with C++20 coroutines (the
// shape of Beast's example/http/server/awaitable), dispatching each request through a Router.
// It owns everything that is not a route's business:
//
//   * keep-alive, and a time limit on every phase: the request header (also the keep-alive idle
//     time), progress of the body (each read must deliver data within body_timeout, so a slow
//     client cannot hold a connection forever), and progress of the response;
//   * a header size limit (431), a body limit per route kind: max_body_bytes for ordinary routes,
//     max_upload_bytes for streaming routes. A Content-Length over the limit is answered with
//     413 before any body byte is read (and before "100 Continue" is sent);
//   * at most max_connections concurrent connections, and at most max_connections_per_address
//     from one client address; further clients get 503 + Retry-After, except that a GET or HEAD
//     of an always-reachable path (/healthz) is still answered on such a connection;
//   * the streaming routes' work (the handler, every BodySink call and the sink's destruction:
//     disk writes, zip extraction, photo checks, fsync, removing temporary folders) runs on a
//     separate pool of blocking_threads threads, never on the I/O threads, so a large upload's
//     final work cannot delay other requests (/healthz, status polls);
//   * the optional bearer token (401 + WWW-Authenticate) on every path but public_paths;
//   * the headers every response carries (Server, Content-Type, X-Request-Id, Connection), one
//     access-log line per request (method, path, status, bytes, milliseconds, client, id), and a
//     catch-all that turns any exception from a handler into a 500 JSON error;
//   * SIGINT/SIGTERM: stop accepting, close idle keep-alive connections, let in-flight requests
//     finish within shutdown_grace, then close what is left; Run() then returns OK.
//
// Usage (see server/main.cc):
//   HttpServer server(options, std::move(router));
//   if (Status s = server.Listen(); !s.ok()) { ...port taken... }
//   std::cout << "listening on " << server.port();
//   Status s = server.Run();   // blocks until shutdown
//
// All Beast and Asio code is confined to server.cc; this header only declares.
#ifndef RECONDUIT_SERVER_HTTP_SERVER_H_
#define RECONDUIT_SERVER_HTTP_SERVER_H_

#include "core/util/status.h"
#include "server/http/http_metrics.h"
#include "server/http/router.h"

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace reconduit::server {

struct HttpServerOptions {
  // Address to bind: an IP address or a host name ("0.0.0.0" for all IPv4 interfaces).
  std::string host = "127.0.0.1";
  // TCP port; 0 picks a free ephemeral port (read it back with HttpServer::port()).
  int port = 8080;
  // Threads running the I/O loop, [1, 64]. Handlers run on them, so a few suffice: the server
  // only moves bytes and does short database transactions.
  int num_threads = 2;
  // Concurrent connections, >= 1; more are answered 503 with Retry-After and closed.
  int max_connections = 256;
  // Concurrent connections from one client address, >= 1 (a value over max_connections
  // means no separate cap); more from that address are answered 503 with Retry-After, so one
  // address cannot take the whole pool.
  int max_connections_per_address = 32;
  // Threads that run the streaming routes' handlers and body sinks (uploads: disk writes, zip
  // extraction, photo checks, fsync), [1, 64]. Work beyond them waits in a queue; the number of
  // uploads at once is bounded by the upload route itself (max_concurrent_uploads).
  int blocking_threads = 4;
  // Maximum size in bytes of a request line plus headers; larger requests get 431.
  std::uint32_t max_header_bytes = 16 * 1024;
  // Maximum body in bytes of ordinary (buffered) routes; JSON requests are small.
  std::uint64_t max_body_bytes = 1024 * 1024;
  // Maximum body in bytes of streaming routes (uploads); nothing larger is ever accepted.
  std::uint64_t max_upload_bytes = std::uint64_t{4} * 1024 * 1024 * 1024;
  // Time allowed for a complete request header, also the idle time of a keep-alive connection.
  std::chrono::milliseconds header_timeout{30000};
  // Longest wait for the next piece of a request body.
  std::chrono::milliseconds body_timeout{30000};
  // Longest wait for the client to accept the next piece of a response.
  std::chrono::milliseconds write_timeout{30000};
  // How long in-flight requests may run after a shutdown signal before connections are closed.
  std::chrono::milliseconds shutdown_grace{10000};
  // When non-empty, every request except those to public_paths needs
  // `Authorization: Bearer <bearer_token>`.
  std::string bearer_token;
  // Exact request paths reachable without the token.
  std::vector<std::string> public_paths = {"/healthz"};
  // Exact request paths (GET/HEAD, ordinary routes) still answered on a connection refused for
  // the connection caps: the request header is read (within a short time) and, when it asks
  // for one of these, it is served; anything else gets the 503.
  std::vector<std::string> always_reachable_paths = {"/healthz"};
  // Value of the Server header.
  std::string server_name = "reconduit";
  // Seconds in Retry-After when the server is full (503) or a handler reports
  // kResourceExhausted.
  int retry_after_seconds = 5;
  // When set, every response is counted by status here (for GET /metrics). Shared with the
  // handler that reports it.
  std::shared_ptr<HttpMetrics> metrics;
  // Install SIGINT/SIGTERM handlers in Run(). Off for servers embedded in tests, which call
  // HttpServer::Shutdown() instead.
  bool handle_signals = true;

  // Returns false and a message naming the bad field when an option is out of range.
  bool Check(std::string* error) const;
};

class HttpServer {
 public:
  // Throws CheckError when !options.Check().
  HttpServer(HttpServerOptions options, Router router);
  ~HttpServer();
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  // Binds and listens. Returns kFailedPrecondition with a message naming the address and the
  // system error when the address cannot be bound (port taken, permission denied, unknown
  // host). Call once, before Run().
  Status Listen();
  // The bound port (the actual one when options.port was 0); 0 before Listen().
  int port() const;

  // Serves until a shutdown signal or Shutdown(), on options.num_threads threads (the calling
  // thread is one of them). Returns OK after a graceful shutdown.
  Status Run();

  // Starts a graceful shutdown, as SIGTERM does. Thread-safe; may be called before Run().
  void Shutdown();

  // Connections currently open (for tests and metrics). Thread-safe.
  int ConnectionCount() const;

 private:
  class Impl;
  std::shared_ptr<Impl> impl_;
};

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_HTTP_SERVER_H_
