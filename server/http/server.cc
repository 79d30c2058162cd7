// The only translation unit of reconduit_http that includes Beast's I/O machinery: the listener,
// the session loop, response serialisation and shutdown. Laid out top-down like the Beast
// examples: helpers, response writing, request handling, session, listener and shutdown.
#include "server/http/server.h"

#include "core/util/logging.h"
#include "server/http/url.h"

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/redirect_error.hpp>
#include <boost/asio/signal_set.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/strand.hpp>
#include <boost/asio/thread_pool.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>

#include <algorithm>
#include <array>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <exception>
#include <limits>
#include <mutex>
#include <random>
#include <thread>
#include <type_traits>
#include <unordered_map>
#include <unordered_set>
#include <variant>

namespace reconduit::server {

namespace beast = boost::beast;
namespace http = beast::http;
namespace net = boost::asio;
using tcp = net::ip::tcp;

namespace {

// Size of the buffer a request body is read into; also the largest piece a BodySink receives.
constexpr std::size_t kBodyChunkBytes = 64 * 1024;
// Body bytes collected before a BodySink is called on the blocking pool.
constexpr std::size_t kSinkBatchBytes = 1024 * 1024;
// Room reserved in a connection's read buffer while it reads a body. Beast reads only into the
// buffer's free capacity (at least 512 bytes): left at what the header needed (about 1.5 KiB),
// a body came in 1.5 KiB reads, each waiting its turn behind every other connection's handlers,
// so a 0.5 MB upload took 3 s beside 200 busy pollers and 5 s beside 1000.
constexpr std::size_t kBodyReadBufferBytes = 256 * 1024;
// After an early error response on a connection whose request body was not read, the server
// reads and discards this much for at most kLingerTime before closing, so the client sees the
// response instead of a connection reset.
constexpr std::uint64_t kLingerMaxBytes = 4 * 1024 * 1024;
constexpr std::chrono::milliseconds kLingerTime{2000};
// A connection refused for the connection caps may still ask for an always-reachable path
// (/healthz): its request header is awaited this long before the 503 is sent.
constexpr std::chrono::milliseconds kRejectHeaderTimeout{1000};

auto Awaitable(beast::error_code& ec) { return net::redirect_error(net::use_awaitable, ec); }

std::string ToString(beast::string_view s) { return std::string(s.data(), s.size()); }

// 16 hex digits from a per-thread generator seeded by the system.
std::string NewRequestId() {
  thread_local std::mt19937_64 generator{std::random_device{}()};
  char buffer[17];
  std::snprintf(buffer, sizeof(buffer), "%016llx",
                static_cast<unsigned long long>(generator()));  // NOLINT(runtime/int)
  return buffer;
}

// A client-supplied X-Request-Id is echoed only when it is short and harmless in a log line.
bool IsAcceptableRequestId(std::string_view id) {
  if (id.empty() || id.size() > 64) return false;
  for (const char c : id) {
    const bool ok = (c >= '0' && c <= '9') || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
                    c == '-' || c == '_' || c == '.';
    if (!ok) return false;
  }
  return true;
}

// True for a Transfer-Encoding value that is exactly "chunked" (any case, white space around).
bool IsPlainChunked(std::string_view value) {
  while (!value.empty() && (value.front() == ' ' || value.front() == '\t')) value.remove_prefix(1);
  while (!value.empty() && (value.back() == ' ' || value.back() == '\t')) value.remove_suffix(1);
  return EqualsIgnoreCase(value, "chunked");
}

// `value` in double quotes for a message, cut at 64 bytes, printable ASCII only.
std::string QuoteForLog(std::string_view value) {
  std::string quoted = "\"";
  for (const char c : value.substr(0, 64)) quoted += (c >= 0x20 && c < 0x7F && c != '"') ? c : '?';
  return quoted + "\"";
}

bool IsParseError(const beast::error_code& ec) {
  return ec.category() == http::make_error_code(http::error::bad_target).category() &&
         ec != http::error::end_of_stream && ec != http::error::partial_message;
}

// Checks `Authorization: Bearer <token>`; the scheme is case-insensitive (RFC 9110 11.1).
bool HasBearerToken(const RequestContext& context, const std::string& token) {
  const std::optional<std::string_view> header = context.Header("Authorization");
  if (!header) return false;
  constexpr std::string_view kScheme = "bearer ";
  if (header->size() < kScheme.size() ||
      !EqualsIgnoreCase(header->substr(0, kScheme.size()), kScheme)) {
    return false;
  }
  std::string_view presented = header->substr(kScheme.size());
  while (!presented.empty() && presented.front() == ' ') presented.remove_prefix(1);
  while (!presented.empty() && presented.back() == ' ') presented.remove_suffix(1);
  return ConstantTimeEquals(presented, token);
}

}  // namespace

bool HttpServerOptions::Check(std::string* error) const {
  auto fail = [error](const std::string& message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (host.empty()) return fail("host must not be empty");
  if (port < 0 || port > 65535) return fail("port must be in [0, 65535]");
  if (num_threads < 1 || num_threads > 64) return fail("num_threads must be in [1, 64]");
  if (max_connections < 1) return fail("max_connections must be >= 1");
  if (max_connections_per_address < 1) return fail("max_connections_per_address must be >= 1");
  if (blocking_threads < 1 || blocking_threads > 64) {
    return fail("blocking_threads must be in [1, 64]");
  }
  if (max_header_bytes < 1024) return fail("max_header_bytes must be >= 1024");
  if (max_body_bytes < 1) return fail("max_body_bytes must be >= 1");
  if (max_upload_bytes < 1) return fail("max_upload_bytes must be >= 1");
  if (header_timeout.count() <= 0 || body_timeout.count() <= 0 || write_timeout.count() <= 0) {
    return fail("timeouts must be positive");
  }
  if (shutdown_grace.count() < 0) return fail("shutdown_grace must be >= 0");
  if (retry_after_seconds < 0) return fail("retry_after_seconds must be >= 0");
  if (bearer_token.find_first_of(" \t\r\n") != std::string::npos) {
    return fail("bearer_token must not contain white space");
  }
  return true;
}

//------------------------------------------------------------------------------------------------

// One accepted connection. The session coroutine and the shutdown code share it; `idle` is only
// touched on the connection's strand.
struct Connection {
  explicit Connection(tcp::socket socket) : stream(std::move(socket)) {
    beast::error_code ec;
    const tcp::endpoint remote = stream.socket().remote_endpoint(ec);
    address = ec ? std::string("unknown") : remote.address().to_string();
  }
  beast::tcp_stream stream;
  // The client's IP address ("unknown" when the socket could not tell).
  std::string address;
  // True while waiting for the next request header (nothing in flight).
  bool idle = false;
};

class HttpServer::Impl : public std::enable_shared_from_this<HttpServer::Impl> {
 public:
  Impl(HttpServerOptions options, Router router)
      : options_(std::move(options)),
        router_(std::move(router)),
        blocking_pool_(static_cast<std::size_t>(options_.blocking_threads)),
        control_(net::make_strand(ioc_)),
        acceptor_(control_),
        signals_(control_) {}

  Status Listen();
  Status Run();
  void Shutdown();
  int port() const { return bound_port_; }
  int ConnectionCount() const {
    std::lock_guard<std::mutex> lock(connections_mutex_);
    return static_cast<int>(connections_.size());
  }

 private:
  // The handler chosen for a request that passed Admit().
  struct Dispatch {
    const Handler* handler = nullptr;
    const StreamingHandler* streaming_handler = nullptr;
    bool blocking = false;  // `handler` runs on the blocking pool.
    std::uint64_t body_limit = 0;
  };

  // What HandleRequest decided about the connection.
  struct Outcome {
    bool keep_alive = false;
    // The request body was not (completely) read: linger before closing.
    bool body_unread = false;
  };

  net::awaitable<void> AcceptLoop();
  // Admits an accepted connection (or sends it its 503 when over a cap) and runs its session.
  void StartSession(tcp::socket socket);
  net::awaitable<void> WaitForShutdown();
  net::awaitable<void> Session(std::shared_ptr<Connection> connection);
  net::awaitable<void> RejectBusy(std::shared_ptr<Connection> connection);
  // Registers an accepted connection unless a connection cap is reached.
  bool TryAddConnection(const std::shared_ptr<Connection>& connection);
  void RemoveConnection(const std::shared_ptr<Connection>& connection);
  // Runs `step` on the blocking pool and resumes on the calling coroutine's executor with what
  // it returned. `step` must not throw (wrap it in Guarded) and its result must be
  // default-constructible.
  template <class Step>
  net::awaitable<std::invoke_result_t<Step&>> OnBlockingPool(Step& step);
  // Gives `data` to the sink on the blocking pool, in pieces of at most kBodyChunkBytes; returns
  // the sink's early response (or a 500 when it threw).
  net::awaitable<std::optional<Response>> FeedSink(const RequestContext& context,
                                                   std::unique_ptr<BodySink>& sink,
                                                   std::string_view data);
  // Destroys a sink (which may remove a folder of temporary files) on the blocking pool.
  net::awaitable<void> DropSink(const RequestContext& context, std::unique_ptr<BodySink>& sink);
  // Everything decided from the header alone: target, token, size limits, route. Returns the
  // refusal to send, or nullopt with `dispatch` filled in.
  std::optional<Response> Admit(RequestContext& context, Dispatch* dispatch);
  net::awaitable<Outcome> HandleRequest(Connection& connection,
                                        http::request_parser<http::buffer_body>& parser,
                                        beast::flat_buffer& buffer,
                                        std::vector<char>& chunk,
                                        const std::string& remote_address);
  // Reads the request body into context.body, or piece by piece into `sink` when it is set.
  // Sets `refusal` when the sink refuses or the body is too large or malformed. Returns false
  // when nobody is listening any more (write of 100 Continue failed, timeout, disconnect):
  // then no response is sent.
  net::awaitable<bool> ReadBody(beast::tcp_stream& stream,
                                http::request_parser<http::buffer_body>& parser,
                                beast::flat_buffer& buffer,
                                std::vector<char>& chunk,
                                RequestContext& context,
                                std::uint64_t body_limit,
                                std::unique_ptr<BodySink>& sink,
                                std::optional<Response>& refusal);
  // Writes `response` and logs the request; returns false when the write failed.
  net::awaitable<bool> WriteResponse(beast::tcp_stream& stream,
                                     const RequestContext& context,
                                     Response& response,
                                     bool keep_alive,
                                     std::chrono::steady_clock::time_point start);
  template <class Message>
  net::awaitable<bool> WriteMessage(beast::tcp_stream& stream, Message& message);
  // Writes a streamed (chunked) response; adds the bytes sent to *body_bytes.
  template <class FillHeaders>
  net::awaitable<bool> WriteStream(beast::tcp_stream& stream,
                                   const RequestContext& context,
                                   Response& response,
                                   FillHeaders& fill_headers,
                                   std::uint64_t* body_bytes);
  net::awaitable<void> Linger(beast::tcp_stream& stream);

  void CloseConnections(bool only_idle);
  void RunLoop();

  HttpServerOptions options_;
  Router router_;
  net::io_context ioc_;
  // Runs what may block on the disk (the streaming routes' handlers and sinks), so that the I/O
  // threads only move bytes.
  net::thread_pool blocking_pool_;
  // Serialises the acceptor, the signal set and the shutdown sequence.
  net::strand<net::io_context::executor_type> control_;
  tcp::acceptor acceptor_;
  net::signal_set signals_;
  int bound_port_ = 0;
  std::string bound_address_;

  std::atomic<bool> stopping_{false};
  std::atomic<bool> shutdown_requested_{false};
  mutable std::mutex connections_mutex_;
  std::unordered_set<std::shared_ptr<Connection>> connections_;
  // Open connections per client address (entries with a count of zero are erased).
  std::unordered_map<std::string, int> connections_per_address_;
  // Refused connections still being answered; beyond max_connections they are closed at once.
  std::atomic<int> rejecting_{0};
};

template <class Step>
net::awaitable<std::invoke_result_t<Step&>> HttpServer::Impl::OnBlockingPool(Step& step) {
  using StepResult = std::invoke_result_t<Step&>;
  // co_spawn runs the coroutine on the pool; use_awaitable resumes this coroutine on its own
  // executor (the connection's strand) when it is done.
  auto run = [&step]() -> net::awaitable<StepResult> { co_return step(); };
  auto operation = net::co_spawn(blocking_pool_.get_executor(), std::move(run), net::use_awaitable);
  StepResult result = co_await std::move(operation);
  co_return result;
}

//------------------------------------------------------------------------------------------------
// Response writing.

namespace {

// The catch-all at the request boundary: runs a handler step and turns an exception into
// nullopt plus a log line; the caller answers with a 500 JSON error.
template <class Step>
auto Guarded(const RequestContext& context, Step&& step) -> std::optional<decltype(step())> {
  try {
    return step();
  } catch (const std::exception& e) {
    LOG_ERROR << "uncaught exception in handler for " << context.method_string << " "
              << context.path << " id=" << context.request_id << ": " << e.what();
  } catch (...) {
    LOG_ERROR << "uncaught non-standard exception in handler for " << context.method_string << " "
              << context.path << " id=" << context.request_id;
  }
  return std::nullopt;
}

Response InternalError(const RequestContext& context) {
  return ErrorResponse(HttpStatus::internal_server_error,
                       "internal server error (request id " + context.request_id + ")");
}

}  // namespace

namespace {

// A body of `length` bytes read from `offset` of an open file: whole files and Range requests.
// (Beast's file_body always sends the whole file.) Shaped like beast::http::basic_file_body.
struct FileSliceBody {
  struct value_type {
    beast::file file;
    std::uint64_t offset = 0;
    std::uint64_t length = 0;
  };

  static std::uint64_t size(const value_type& body) { return body.length; }

  class writer {
   public:
    using const_buffers_type = net::const_buffer;

    template <bool kIsRequest, class Fields>
    writer(http::header<kIsRequest, Fields>& /*header*/, value_type& body) : body_(body) {}

    void init(beast::error_code& ec) {
      remaining_ = body_.length;
      body_.file.seek(body_.offset, ec);
    }

    boost::optional<std::pair<const_buffers_type, bool>> get(beast::error_code& ec) {
      const std::size_t amount =
          static_cast<std::size_t>(std::min<std::uint64_t>(remaining_, buffer_.size()));
      if (amount == 0) {
        ec = {};
        return boost::none;
      }
      const std::size_t n = body_.file.read(buffer_.data(), amount, ec);
      if (ec) return boost::none;
      if (n == 0) {
        // The file became shorter than the size announced in Content-Length.
        ec = boost::system::errc::make_error_code(boost::system::errc::io_error);
        return boost::none;
      }
      remaining_ -= n;
      return std::make_pair(net::const_buffer(buffer_.data(), n), remaining_ > 0);
    }

   private:
    value_type& body_;
    std::uint64_t remaining_ = 0;
    std::array<char, kBodyChunkBytes> buffer_;
  };
};

}  // namespace

template <class Message>
net::awaitable<bool> HttpServer::Impl::WriteMessage(beast::tcp_stream& stream, Message& message) {
  // Piecewise with a timeout per piece, so a large download to a slow but live client is not cut
  // off while a client that stops reading is.
  http::serializer<false, typename Message::body_type, typename Message::fields_type> serializer(
      message);
  beast::error_code ec;
  while (!serializer.is_done()) {
    stream.expires_after(options_.write_timeout);
    co_await http::async_write_some(stream, serializer, Awaitable(ec));
    if (ec) {
      LOG_DEBUG << "write failed: " << ec.message();
      co_return false;
    }
  }
  co_return true;
}

template <class FillHeaders>
net::awaitable<bool> HttpServer::Impl::WriteStream(beast::tcp_stream& stream,
                                                   const RequestContext& context,
                                                   Response& response,
                                                   FillHeaders& fill_headers,
                                                   std::uint64_t* body_bytes) {
  // The header with chunked transfer coding, then one chunk per non-empty step, then the last
  // chunk (Beast's "chunked encoding" pattern). Between steps the coroutine sleeps on a timer,
  // so a long-lived stream costs no thread.
  http::response<http::empty_body> message{response.status(), 11};
  fill_headers(message);
  message.chunked(true);
  http::response_serializer<http::empty_body> serializer(message);
  beast::error_code ec;
  stream.expires_after(options_.write_timeout);
  co_await http::async_write_header(stream, serializer, Awaitable(ec));
  if (ec) co_return false;

  const StreamProducer& producer = response.stream_producer();
  net::steady_timer timer(stream.get_executor());
  while (true) {
    const bool stopping = stopping_;
    std::optional<StreamStep> step = Guarded(context, [&] { return producer(); });
    if (step && !step->data.empty()) {
      *body_bytes += step->data.size();
      auto chunk = http::make_chunk(net::const_buffer(step->data.data(), step->data.size()));
      stream.expires_after(options_.write_timeout);
      co_await net::async_write(stream, chunk, Awaitable(ec));
      if (ec) co_return false;
    }
    if (!step || step->done || stopping) break;
    timer.expires_after(response.stream_poll_interval());
    co_await timer.async_wait(Awaitable(ec));
  }
  auto last = http::make_chunk_last();
  stream.expires_after(options_.write_timeout);
  co_await net::async_write(stream, last, Awaitable(ec));
  co_return !ec;
}

net::awaitable<bool> HttpServer::Impl::WriteResponse(beast::tcp_stream& stream,
                                                     const RequestContext& context,
                                                     Response& response,
                                                     bool keep_alive,
                                                     std::chrono::steady_clock::time_point start) {
  const bool head = context.method == HttpVerb::head;

  // Open a file body first: a file that vanished (or shrank below the slice) becomes a 404.
  FileSliceBody::value_type file;
  if (response.file()) {
    beast::error_code ec;
    file.file.open(response.file()->c_str(), beast::file_mode::scan, ec);
    const std::uint64_t file_size = ec ? 0 : file.file.size(ec);
    if (!ec) {
      const FileSlice slice = response.file_slice().value_or(FileSlice{0, file_size});
      if (slice.offset > file_size || slice.length > file_size - slice.offset) {
        ec = boost::system::errc::make_error_code(boost::system::errc::invalid_seek);
      }
      file.offset = slice.offset;
      file.length = slice.length;
    }
    if (ec) {
      LOG_WARNING << "cannot open " << *response.file() << ": " << ec.message();
      response = ErrorResponse(HttpStatus::not_found, "file not found");
    }
  }
  const bool is_file = response.file().has_value();
  const bool is_stream = static_cast<bool>(response.stream_producer());
  std::uint64_t body_bytes = is_file ? file.length : response.body().size();
  if (options_.metrics != nullptr) {
    options_.metrics->CountResponse(static_cast<unsigned>(response.status()));
  }

  auto fill_headers = [&](auto& message) {
    for (const auto& [name, value] : response.headers()) message.set(name, value);
    message.set(http::field::server, options_.server_name);
    if (response.FindHeader("Content-Type") == nullptr) {
      message.set(http::field::content_type, std::string(kTextContentType));
    }
    message.set("X-Request-Id", context.request_id);
    message.set("X-Content-Type-Options", "nosniff");
    message.keep_alive(keep_alive);
  };

  bool written = false;
  if (head) {
    http::response<http::empty_body> message{response.status(), 11};
    fill_headers(message);
    if (!is_stream) message.content_length(body_bytes);
    body_bytes = 0;
    written = co_await WriteMessage(stream, message);
  } else if (is_file) {
    http::response<FileSliceBody> message{response.status(), 11};
    fill_headers(message);
    message.body() = std::move(file);
    message.prepare_payload();
    written = co_await WriteMessage(stream, message);
  } else if (is_stream) {
    body_bytes = 0;
    written = co_await WriteStream(stream, context, response, fill_headers, &body_bytes);
  } else {
    http::response<http::string_body> message{response.status(), 11};
    fill_headers(message);
    message.body() = response.body();
    message.prepare_payload();
    written = co_await WriteMessage(stream, message);
  }

  const auto elapsed =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start);
  char elapsed_text[32];
  std::snprintf(elapsed_text, sizeof(elapsed_text), "%.1f", elapsed.count());
  LOG_INFO << "http " << (context.method_string.empty() ? "-" : context.method_string) << " "
           << (context.path.empty() ? "-" : context.path) << " "
           << static_cast<unsigned>(response.status()) << " " << body_bytes << "B " << elapsed_text
           << "ms " << context.remote_address << " id=" << context.request_id
           << (written ? "" : " (write failed)");
  co_return written;
}

net::awaitable<void> HttpServer::Impl::Linger(beast::tcp_stream& stream) {
  beast::error_code ec;
  stream.socket().shutdown(tcp::socket::shutdown_send, ec);
  if (ec) co_return;
  std::array<char, 16 * 1024> discard;
  std::uint64_t total = 0;
  stream.expires_after(kLingerTime);
  while (total < kLingerMaxBytes) {
    const std::size_t n = co_await stream.async_read_some(net::buffer(discard), Awaitable(ec));
    if (ec) break;
    total += n;
  }
}

//------------------------------------------------------------------------------------------------
// Request handling.

std::optional<Response> HttpServer::Impl::Admit(RequestContext& context, Dispatch* dispatch) {
  Result<TargetParts> target = SplitTarget(context.target);
  if (!target.ok()) return ErrorResponse(HttpStatus::bad_request, target.status().message());
  context.path = target->path;
  Result<KeyValues> query = ParseQuery(target->query);
  if (!query.ok()) return ErrorResponse(HttpStatus::bad_request, query.status().message());
  context.query = std::move(*query);

  // Transfer codings other than chunked alone (gzip, deflate, "gzip, chunked") are not
  // decoded: refuse them (RFC 9112 6.1) instead of reading a coded body as if it were plain.
  for (const auto& [name, value] : context.headers) {
    if (EqualsIgnoreCase(name, "Transfer-Encoding") && !IsPlainChunked(value)) {
      return ErrorResponse(HttpStatus::not_implemented,
                           "Transfer-Encoding " + QuoteForLog(value) +
                               " is not supported; send the body as it is or chunked alone");
    }
  }

  // Authentication comes before routing, so that unknown paths reveal nothing without a token.
  if (!options_.bearer_token.empty()) {
    bool is_public = false;
    for (const std::string& path : options_.public_paths) is_public |= path == context.path;
    if (!is_public && !HasBearerToken(context, options_.bearer_token)) {
      return UnauthorizedResponse(context.Header("Authorization")
                                      ? "invalid bearer token"
                                      : "this server requires an Authorization: Bearer token");
    }
  }

  // Nothing larger than the largest upload is accepted anywhere: refuse before routing.
  if (context.content_length && *context.content_length > options_.max_upload_bytes) {
    return ErrorResponse(HttpStatus::payload_too_large,
                         "request body of " + std::to_string(*context.content_length) +
                             " bytes exceeds the limit of " +
                             std::to_string(options_.max_upload_bytes) + " bytes");
  }

  RouteMatch match = router_.Match(context.method, context.path);
  switch (match.kind) {
    case RouteMatch::Kind::kBadPath:
      return ErrorResponse(HttpStatus::bad_request, "malformed request path");
    case RouteMatch::Kind::kNotFound:
      return ErrorResponse(HttpStatus::not_found, "no route for " + context.path);
    case RouteMatch::Kind::kMethodNotAllowed:
      return MethodNotAllowedResponse(match.allow);
    case RouteMatch::Kind::kFallback:
      dispatch->handler = &router_.fallback();
      break;
    case RouteMatch::Kind::kFound:
      context.path_params = std::move(match.path_params);
      if (match.route->streaming_handler) {
        dispatch->streaming_handler = &match.route->streaming_handler;
      } else {
        dispatch->handler = &match.route->handler;
        dispatch->blocking = match.route->blocking;
      }
      break;
  }

  dispatch->body_limit =
      dispatch->streaming_handler != nullptr ? options_.max_upload_bytes : options_.max_body_bytes;
  if (context.content_length && *context.content_length > dispatch->body_limit) {
    return ErrorResponse(HttpStatus::payload_too_large,
                         "request body of " + std::to_string(*context.content_length) +
                             " bytes exceeds the limit of " + std::to_string(dispatch->body_limit) +
                             " bytes for this route");
  }
  return std::nullopt;
}

namespace {

// What the handlers know of a request once its header is in: method, target, headers, the
// request id (the client's X-Request-Id when acceptable, else a new one), Content-Length.
RequestContext ContextFromHeader(const http::request_parser<http::buffer_body>& parser,
                                 const std::string& remote_address) {
  const auto& request = parser.get();
  RequestContext context;
  context.method = request.method();
  context.method_string = ToString(request.method_string());
  context.target = ToString(request.target());
  context.remote_address = remote_address;
  for (const auto& field : request) {
    context.headers.emplace_back(ToString(field.name_string()), ToString(field.value()));
  }
  const std::optional<std::string_view> client_id = context.Header("X-Request-Id");
  context.request_id =
      client_id && IsAcceptableRequestId(*client_id) ? std::string(*client_id) : NewRequestId();
  if (parser.content_length()) context.content_length = *parser.content_length();
  return context;
}

// Calls a streaming handler before the body is read. Returns the refusal it answered with
// (or a 500 when it threw or returned no sink), or nullopt with its sink in *sink.
std::optional<Response> StartStreaming(RequestContext& context,
                                       const StreamingHandler& handler,
                                       std::unique_ptr<BodySink>* sink) {
  std::optional<StreamStart> stream_start = Guarded(context, [&] { return handler(context); });
  if (!stream_start) return InternalError(context);
  if (auto* response = std::get_if<Response>(&*stream_start)) return std::move(*response);
  *sink = std::move(std::get<std::unique_ptr<BodySink>>(*stream_start));
  if (*sink == nullptr) {
    LOG_ERROR << "streaming handler for " << context.path << " returned a null sink";
    return InternalError(context);
  }
  return std::nullopt;
}

// The answer to a body read that failed with `ec`: 413 over the limit, 400 for a malformed
// body, nullopt when nobody is listening any more (timeout or disconnect; logged).
std::optional<Response> BodyReadFailure(const RequestContext& context,
                                        const beast::error_code& ec,
                                        std::uint64_t body_limit) {
  if (ec == http::error::body_limit) {
    return ErrorResponse(HttpStatus::payload_too_large, "request body exceeds the limit of " +
                                                            std::to_string(body_limit) + " bytes");
  }
  if (IsParseError(ec)) {
    return ErrorResponse(HttpStatus::bad_request, "malformed request body: " + ec.message());
  }
  LOG_INFO << "http " << context.method_string << " " << context.path
           << " aborted while reading the body: " << ec.message() << " " << context.remote_address
           << " id=" << context.request_id;
  return std::nullopt;
}

}  // namespace

net::awaitable<void> HttpServer::Impl::DropSink(const RequestContext& context,
                                                std::unique_ptr<BodySink>& sink) {
  if (sink == nullptr) co_return;
  auto drop = [&] {
    return Guarded(context, [&] {
      sink.reset();
      return true;
    });
  };
  co_await OnBlockingPool(drop);
}

net::awaitable<std::optional<Response>> HttpServer::Impl::FeedSink(const RequestContext& context,
                                                                   std::unique_ptr<BodySink>& sink,
                                                                   std::string_view data) {
  auto feed = [&]() -> std::optional<Response> {
    while (!data.empty()) {
      const std::string_view piece = data.substr(0, kBodyChunkBytes);
      data.remove_prefix(piece.size());
      std::optional<std::optional<Response>> early =
          Guarded(context, [&] { return sink->OnData(piece); });
      if (!early) return InternalError(context);
      if (*early) return std::move(*early);
    }
    return std::nullopt;
  };
  std::optional<Response> refusal = co_await OnBlockingPool(feed);
  co_return refusal;
}

net::awaitable<bool> HttpServer::Impl::ReadBody(beast::tcp_stream& stream,
                                                http::request_parser<http::buffer_body>& parser,
                                                beast::flat_buffer& buffer,
                                                std::vector<char>& chunk,
                                                RequestContext& context,
                                                std::uint64_t body_limit,
                                                std::unique_ptr<BodySink>& sink,
                                                std::optional<Response>& refusal) {
  auto& request = parser.get();
  // Enforces the limit on chunked bodies, whose size is unknown up front.
  parser.body_limit(body_limit);
  const std::optional<std::string_view> expect = context.Header("Expect");
  if (expect && EqualsIgnoreCase(*expect, "100-continue")) {
    http::response<http::empty_body> go_on{http::status::continue_, 11};
    const bool written = co_await WriteMessage(stream, go_on);
    if (!written) co_return false;
  }
  beast::error_code ec;
  // A small body (a JSON request) needs no more than itself.
  buffer.reserve(buffer.size() +
                 static_cast<std::size_t>(std::min<std::uint64_t>(
                     kBodyReadBufferBytes, context.content_length.value_or(kBodyReadBufferBytes))));
  // A sink gets the body in batches of up to kSinkBatchBytes, one trip to the blocking pool
  // each (in pieces of at most kBodyChunkBytes): a trip per 64 KiB piece made uploads three
  // times slower on a loaded machine. A batch is fed early when no more bytes are waiting.
  std::vector<char> batch(sink != nullptr ? kSinkBatchBytes : 0);
  std::vector<char>& target = sink != nullptr ? batch : chunk;
  std::size_t filled = 0;
  while (!parser.is_done()) {
    request.body().data = target.data() + filled;
    request.body().size = target.size() - filled;
    stream.expires_after(options_.body_timeout);
    co_await http::async_read_some(stream, buffer, parser, Awaitable(ec));
    if (ec == http::error::need_buffer) ec = {};
    if (ec) break;
    filled = target.size() - request.body().size;
    if (sink == nullptr) {
      context.body.append(chunk.data(), filled);
      filled = 0;
      continue;
    }
    // Feed the batch when it is full, the body is done, or nothing more has arrived yet (a
    // slow client's bytes go to the sink as they come, not when 1 MiB has gathered).
    beast::error_code available_ec;
    const bool more_waiting = buffer.size() > 0 || stream.socket().available(available_ec) > 0;
    if (filled < target.size() && !parser.is_done() && more_waiting) continue;
    if (filled > 0) {
      refusal = co_await FeedSink(context, sink, std::string_view(batch.data(), filled));
    }
    filled = 0;
    if (refusal) break;
  }
  request.body().data = nullptr;
  request.body().size = 0;
  // An idle keep-alive connection keeps only what a header needs.
  if (buffer.size() == 0) buffer.shrink_to_fit();
  if (!ec) co_return true;
  if (sink != nullptr) {
    const std::string reason = ec.message();
    auto abort = [&] {
      return Guarded(context, [&] {
        sink->OnAbort(reason);
        return true;
      });
    };
    co_await OnBlockingPool(abort);
  }
  co_await DropSink(context, sink);
  refusal = BodyReadFailure(context, ec, body_limit);
  co_return refusal.has_value();
}

// Note on the coroutines in this file: GCC 12 mishandles non-trivial temporaries inside co_await
// expressions (a Response temporary was destroyed twice), so awaited calls get named lvalues only.
net::awaitable<HttpServer::Impl::Outcome> HttpServer::Impl::HandleRequest(
    Connection& connection,
    http::request_parser<http::buffer_body>& parser,
    beast::flat_buffer& buffer,
    std::vector<char>& chunk,
    const std::string& remote_address) {
  const auto start = std::chrono::steady_clock::now();
  beast::tcp_stream& stream = connection.stream;
  RequestContext context = ContextFromHeader(parser, remote_address);

  Outcome outcome;
  outcome.keep_alive = parser.get().keep_alive() && !stopping_;
  const bool has_body = !parser.is_done();

  // A response sent before the body was completely read; the connection is not reused then.
  Dispatch dispatch;
  std::optional<Response> refusal = Admit(context, &dispatch);
  std::unique_ptr<BodySink> sink;
  if (!refusal && dispatch.streaming_handler != nullptr) {
    // Streaming routes touch the disk: their handler and sink run on the blocking pool.
    auto start_streaming = [&] {
      return StartStreaming(context, *dispatch.streaming_handler, &sink);
    };
    refusal = co_await OnBlockingPool(start_streaming);
  }
  // Read the body: into context.body, or piece by piece into the sink.
  if (!refusal && has_body) {
    const bool listening = co_await ReadBody(stream, parser, buffer, chunk, context,
                                             dispatch.body_limit, sink, refusal);
    if (!listening) co_return Outcome{};
  }

  if (refusal) {
    co_await DropSink(context, sink);
    if (has_body && !parser.is_done()) {
      outcome.keep_alive = false;
      outcome.body_unread = true;
    }
    const bool written =
        co_await WriteResponse(stream, context, *refusal, outcome.keep_alive, start);
    if (!written) outcome.keep_alive = false;
    co_return outcome;
  }

  std::optional<Response> result;
  if (sink != nullptr) {
    auto complete = [&] { return Guarded(context, [&] { return sink->OnComplete(context); }); };
    result = co_await OnBlockingPool(complete);
    co_await DropSink(context, sink);
  } else if (dispatch.blocking) {
    auto handle = [&] { return Guarded(context, [&] { return (*dispatch.handler)(context); }); };
    result = co_await OnBlockingPool(handle);
  } else {
    result = Guarded(context, [&] { return (*dispatch.handler)(context); });
  }
  if (!result) result = InternalError(context);
  outcome.keep_alive = outcome.keep_alive && !stopping_;
  const bool written = co_await WriteResponse(stream, context, *result, outcome.keep_alive, start);
  if (!written) outcome.keep_alive = false;
  co_return outcome;
}

//------------------------------------------------------------------------------------------------
// Session.

net::awaitable<void> HttpServer::Impl::Session(std::shared_ptr<Connection> connection) {
  beast::tcp_stream& stream = connection->stream;
  beast::error_code ec;
  const std::string& remote_address = connection->address;

  beast::flat_buffer buffer;
  std::vector<char> chunk(kBodyChunkBytes);
  bool linger = false;
  while (!stopping_) {
    http::request_parser<http::buffer_body> parser;
    parser.header_limit(options_.max_header_bytes);
    // The limit depends on the route, known only after the header: checked in HandleRequest.
    // (Not boost::none: Beast 1.74 compares `len > none` as true and rejects every body.)
    parser.body_limit(std::numeric_limits<std::uint64_t>::max());

    connection->idle = true;
    stream.expires_after(options_.header_timeout);
    co_await http::async_read_header(stream, buffer, parser, Awaitable(ec));
    connection->idle = false;
    if (ec) {
      if (ec == http::error::header_limit || IsParseError(ec)) {
        RequestContext context;
        context.remote_address = remote_address;
        context.request_id = NewRequestId();
        Response response =
            ec == http::error::header_limit
                ? ErrorResponse(HttpStatus::request_header_fields_too_large,
                                "request header exceeds " +
                                    std::to_string(options_.max_header_bytes) + " bytes")
                : ErrorResponse(HttpStatus::bad_request, "malformed HTTP request: " + ec.message());
        const auto now = std::chrono::steady_clock::now();
        co_await WriteResponse(stream, context, response, /*keep_alive=*/false, now);
        linger = true;
      }
      // Otherwise end of stream, timeout, reset or shutdown: close quietly.
      break;
    }
    const Outcome outcome =
        co_await HandleRequest(*connection, parser, buffer, chunk, remote_address);
    if (!outcome.keep_alive) {
      linger = outcome.body_unread;
      break;
    }
  }

  if (linger) {
    // Nothing more will be answered: a shutdown may close this connection at once.
    connection->idle = true;
    co_await Linger(stream);
  } else {
    stream.socket().shutdown(tcp::socket::shutdown_send, ec);
  }
  stream.close();
}

net::awaitable<void> HttpServer::Impl::RejectBusy(std::shared_ptr<Connection> connection) {
  beast::tcp_stream& stream = connection->stream;
  struct Count {
    explicit Count(std::atomic<int>& n) : n(n), before(n.fetch_add(1)) {}
    ~Count() { n.fetch_sub(1); }
    std::atomic<int>& n;
    const int before;
  } const rejecting(rejecting_);
  if (rejecting.before >= options_.max_connections) {
    // A flood of refused connections: no answer for those beyond the cap.
    stream.close();
    co_return;
  }
  const auto start = std::chrono::steady_clock::now();
  // An always-reachable path (/healthz) is still served: wait briefly for the request header.
  beast::flat_buffer buffer;
  http::request_parser<http::buffer_body> parser;
  parser.header_limit(options_.max_header_bytes);
  beast::error_code ec;
  // Not the stream's own timeout, which closes the socket: the 503 must still be sent after a
  // client that sends nothing. The timer cancels the read instead (both run on the strand).
  auto reading = std::make_shared<bool>(true);
  net::steady_timer timer(stream.get_executor());
  timer.expires_after(std::min(kRejectHeaderTimeout, options_.header_timeout));
  timer.async_wait([connection, reading](const beast::error_code& error) {
    beast::error_code ignored;
    if (!error && *reading) connection->stream.socket().cancel(ignored);
  });
  stream.expires_never();
  co_await http::async_read_header(stream, buffer, parser, Awaitable(ec));
  *reading = false;
  timer.cancel();
  RequestContext context;
  std::optional<Response> response;
  if (!ec) {
    context = ContextFromHeader(parser, connection->address);
    const Result<TargetParts> target = SplitTarget(context.target);
    const bool reachable =
        target.ok() && parser.is_done() &&
        (context.method == HttpVerb::get || context.method == HttpVerb::head) &&
        std::find(options_.always_reachable_paths.begin(), options_.always_reachable_paths.end(),
                  target->path) != options_.always_reachable_paths.end();
    Dispatch dispatch;
    if (reachable && !Admit(context, &dispatch) && dispatch.handler != nullptr) {
      response = Guarded(context, [&] { return (*dispatch.handler)(context); });
      if (!response) response = InternalError(context);
    }
  } else {
    context.remote_address = connection->address;
    context.request_id = NewRequestId();
  }
  if (!response) {
    response =
        RetryLaterResponse(HttpStatus::service_unavailable, "too many connections; retry later",
                           options_.retry_after_seconds);
  }
  co_await WriteResponse(stream, context, *response, /*keep_alive=*/false, start);
  co_await Linger(stream);
  stream.close();
}

bool HttpServer::Impl::TryAddConnection(const std::shared_ptr<Connection>& connection) {
  std::lock_guard<std::mutex> lock(connections_mutex_);
  if (static_cast<int>(connections_.size()) >= options_.max_connections) return false;
  int& from_address = connections_per_address_[connection->address];
  if (from_address >= options_.max_connections_per_address) {
    if (from_address == 0) connections_per_address_.erase(connection->address);
    return false;
  }
  ++from_address;
  connections_.insert(connection);
  return true;
}

void HttpServer::Impl::RemoveConnection(const std::shared_ptr<Connection>& connection) {
  std::lock_guard<std::mutex> lock(connections_mutex_);
  if (connections_.erase(connection) == 0) return;
  const auto it = connections_per_address_.find(connection->address);
  if (it != connections_per_address_.end() && --it->second <= 0) {
    connections_per_address_.erase(it);
  }
}

//------------------------------------------------------------------------------------------------
// Listener and shutdown.

Status HttpServer::Impl::Listen() {
  beast::error_code ec;
  tcp::resolver resolver(ioc_);
  const auto endpoints =
      resolver.resolve(options_.host, std::to_string(options_.port), tcp::resolver::passive, ec);
  const std::string address = options_.host + ":" + std::to_string(options_.port);
  if (ec || endpoints.empty()) {
    return Status::FailedPrecondition("cannot listen on " + address +
                                      ": cannot resolve host: " + ec.message());
  }
  const tcp::endpoint endpoint = endpoints.begin()->endpoint();
  acceptor_.open(endpoint.protocol(), ec);
  if (!ec) acceptor_.set_option(net::socket_base::reuse_address(true), ec);
  if (!ec) acceptor_.bind(endpoint, ec);
  if (!ec) acceptor_.listen(net::socket_base::max_listen_connections, ec);
  // AcceptLoop drains the backlog with synchronous accepts that must not wait.
  if (!ec) acceptor_.non_blocking(true, ec);
  if (ec) {
    beast::error_code ignored;
    acceptor_.close(ignored);
    return Status::FailedPrecondition("cannot listen on " + address + ": " + ec.message());
  }
  bound_port_ = acceptor_.local_endpoint(ec).port();
  if (options_.handle_signals) {
    signals_.add(SIGINT);
    signals_.add(SIGTERM);
  }
  return Status::Ok();
}

// The acceptor shares the I/O threads' queue with every connection's handlers, so one accept per
// completion would take in one new connection per round of that queue: with 1000 busy
// connections the last of a burst of new ones waited seconds in the backlog (scripts/
// load_test.py: status p99 11 s). After each completion the backlog is drained with
// non-blocking accepts, up to kAcceptBatch at a time.
net::awaitable<void> HttpServer::Impl::AcceptLoop() {
  constexpr int kAcceptBatch = 256;
  net::steady_timer backoff(control_);
  while (true) {
    beast::error_code ec;
    tcp::socket socket(net::make_strand(ioc_));
    co_await acceptor_.async_accept(socket, Awaitable(ec));
    if (stopping_ || !acceptor_.is_open()) co_return;
    if (ec) {
      // Typically EMFILE: back off instead of spinning, and keep serving.
      LOG_WARNING << "accept failed: " << ec.message();
      backoff.expires_after(std::chrono::milliseconds(100));
      co_await backoff.async_wait(Awaitable(ec));
      continue;
    }
    StartSession(std::move(socket));
    for (int i = 0; i < kAcceptBatch; ++i) {
      tcp::socket more(net::make_strand(ioc_));
      acceptor_.accept(more, ec);
      if (ec) break;  // would_block: the backlog is empty; other errors: the next await says.
      StartSession(std::move(more));
    }
  }
}

void HttpServer::Impl::StartSession(tcp::socket socket) {
  auto self = shared_from_this();
  auto connection = std::make_shared<Connection>(std::move(socket));
  if (!TryAddConnection(connection)) {
    net::co_spawn(connection->stream.get_executor(), RejectBusy(connection),
                  [self](std::exception_ptr) {});
    return;
  }
  net::co_spawn(connection->stream.get_executor(), Session(connection),
                [self, connection](std::exception_ptr error) {
                  if (error) {
                    try {
                      std::rethrow_exception(error);
                    } catch (const std::exception& e) {
                      LOG_ERROR << "connection ended by an exception: " << e.what();
                    } catch (...) {
                      LOG_ERROR << "connection ended by a non-standard exception";
                    }
                  }
                  self->RemoveConnection(connection);
                });
}

void HttpServer::Impl::CloseConnections(bool only_idle) {
  std::vector<std::shared_ptr<Connection>> connections;
  {
    std::lock_guard<std::mutex> lock(connections_mutex_);
    connections.assign(connections_.begin(), connections_.end());
  }
  for (auto& connection : connections) {
    // On the connection's strand, so `idle` and the socket are not raced.
    net::post(connection->stream.get_executor(), [connection, only_idle] {
      if (only_idle && !connection->idle) return;
      beast::error_code ec;
      connection->stream.socket().shutdown(tcp::socket::shutdown_both, ec);
      connection->stream.socket().close(ec);
    });
  }
}

net::awaitable<void> HttpServer::Impl::WaitForShutdown() {
  beast::error_code ec;
  if (!shutdown_requested_) co_await signals_.async_wait(Awaitable(ec));
  LOG_INFO << "shutting down: no longer accepting connections, waiting up to "
           << options_.shutdown_grace.count() << " ms for " << ConnectionCount()
           << " open connection(s)";
  stopping_ = true;
  acceptor_.close(ec);
  signals_.clear(ec);

  // Idle keep-alive connections are closed at once; busy ones finish their request (their
  // response then says Connection: close). Connections that turn idle later are closed by their
  // session, which checks stopping_ before waiting for another request.
  CloseConnections(/*only_idle=*/true);
  const auto deadline = std::chrono::steady_clock::now() + options_.shutdown_grace;
  net::steady_timer timer(control_);
  while (ConnectionCount() > 0 && std::chrono::steady_clock::now() < deadline) {
    timer.expires_after(std::chrono::milliseconds(20));
    co_await timer.async_wait(Awaitable(ec));
  }
  if (const int left = ConnectionCount(); left > 0) {
    LOG_WARNING << "shutdown grace period over: closing " << left << " connection(s)";
    CloseConnections(/*only_idle=*/false);
  }
}

void HttpServer::Impl::RunLoop() {
  // A handler exception escaping run() would be a bug in this file; log it and keep serving.
  while (true) {
    try {
      ioc_.run();
      return;
    } catch (const std::exception& e) {
      LOG_ERROR << "exception escaped the I/O loop: " << e.what();
    }
  }
}

Status HttpServer::Impl::Run() {
  if (!acceptor_.is_open()) {
    return Status::FailedPrecondition("HttpServer::Run() called before a successful Listen()");
  }
  auto log_error = [](std::exception_ptr error) {
    if (!error) return;
    try {
      std::rethrow_exception(error);
    } catch (const std::exception& e) {
      LOG_ERROR << "server task failed: " << e.what();
    }
  };
  net::co_spawn(control_, AcceptLoop(), log_error);
  net::co_spawn(control_, WaitForShutdown(), log_error);

  std::vector<std::thread> threads;
  for (int i = 1; i < options_.num_threads; ++i) threads.emplace_back([this] { RunLoop(); });
  RunLoop();
  for (std::thread& thread : threads) thread.join();
  LOG_INFO << "server stopped";
  return Status::Ok();
}

void HttpServer::Impl::Shutdown() {
  shutdown_requested_ = true;
  // Capturing `this` (not a shared_ptr) avoids a reference cycle through the io_context if Run()
  // is never called; the handler then simply never runs.
  net::post(control_, [this] {
    beast::error_code ec;
    signals_.cancel(ec);
  });
}

//------------------------------------------------------------------------------------------------

HttpServer::HttpServer(HttpServerOptions options, Router router) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  impl_ = std::make_shared<Impl>(std::move(options), std::move(router));
}

HttpServer::~HttpServer() = default;

Status HttpServer::Listen() { return impl_->Listen(); }
int HttpServer::port() const { return impl_->port(); }
Status HttpServer::Run() { return impl_->Run(); }
void HttpServer::Shutdown() { impl_->Shutdown(); }
int HttpServer::ConnectionCount() const { return impl_->ConnectionCount(); }

}  // namespace reconduit::server
