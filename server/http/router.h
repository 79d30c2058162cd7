// The route table: {verb, path pattern, handler} entries, matched per request.
//
// Patterns are absolute paths whose segments are literals or `{name}` parameters, e.g.
// "/api/v1/jobs/{id}/files/{name}". A parameter matches exactly one non-empty segment; its
// percent-decoded value is passed in RequestContext::path_params (an encoded '/' stays inside
// the value, so "{name}" can never span segments). When several patterns match, the one with a
// literal at the first differing segment wins ("/jobs/stats" beats "/jobs/{id}"), whatever the
// registration order.
//
// The last segment may be a tail parameter `{name...}`: it matches one or more remaining
// segments and its value is their decoded forms joined with '/' ("/files/{name...}" matches
// "/files/report/similarity.png" with name = "report/similarity.png"). Empty segments and
// segments holding an encoded '/' do not match, so the value's '/' are exactly the path's
// separators; the handler must still refuse "." and ".." segments before using it as a path.
//
// Matching distinguishes an unknown path (404) from a known path requested with the wrong verb
// (405 with `Allow`). A GET route also answers HEAD (the body is dropped by the transport). An
// optional fallback handler answers GET and HEAD requests whose path matches no pattern; the
// server uses it to serve the web/ folder.
//
// Two kinds of handlers:
//   * Handler: the transport reads the whole body (bounded by max_body_bytes) into
//     RequestContext::body, then calls the handler.
//   * StreamingHandler: called right after the header, before any body byte is read. It either
//     refuses the request with a Response (401, 413, 415, 503...) or returns a BodySink that
//     receives the body in chunks as they arrive (bounded by max_upload_bytes). Uploads use this
//     so a photo set is never held in memory.
//
// Handlers added with Add run on an I/O thread: they must not block for long (reads of the job
// store, which never wait for a lock in WAL mode, small answers). Handlers added with
// AddBlocking run on the transport's blocking pool, like streaming handlers and sinks: those
// that write the store (which can wait up to its busy timeout for another process's lock) or
// remove folders, so that no such wait holds an I/O thread. Exceptions are caught by the
// transport and answered with a 500 JSON error; they never take the server down.
//
// Thread-safety: build the router completely before HttpServer starts; Match() is const and may
// then be called from any number of threads.
#ifndef RECONDUIT_SERVER_HTTP_ROUTER_H_
#define RECONDUIT_SERVER_HTTP_ROUTER_H_

#include "server/http/request_context.h"
#include "server/http/response.h"

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace reconduit::server {

using Handler = std::function<Response(RequestContext& context)>;

// Receives a streamed request body. Owned by the transport for the duration of one request and
// destroyed when it ends, however it ends: release temporary files in the destructor unless
// OnComplete committed them.
class BodySink {
 public:
  virtual ~BodySink() = default;
  // Called with each piece of the body in order (chunked transfer coding already removed);
  // pieces are at most a few tens of KiB and never empty. Returns nullopt to continue, or the
  // response that ends the request early: the rest of the body is not read and the connection
  // is closed after the response.
  virtual std::optional<Response> OnData(std::string_view chunk) = 0;
  // Called once after the last byte; produces the response.
  virtual Response OnComplete(RequestContext& context) = 0;
  // Called instead of OnComplete when the body did not arrive completely (client disconnected,
  // timed out, or exceeded the size limit). No response can be sent after this.
  virtual void OnAbort(std::string_view reason) { (void)reason; }
};

using StreamStart = std::variant<Response, std::unique_ptr<BodySink>>;
using StreamingHandler = std::function<StreamStart(RequestContext& context)>;

struct Route {
  HttpVerb verb = HttpVerb::get;
  std::string pattern;
  // Exactly one of the two is set.
  Handler handler;
  StreamingHandler streaming_handler;
  // For `handler`: run it on the blocking pool (AddBlocking), not on an I/O thread.
  bool blocking = false;

  // The pattern split at '/'; parameters are stored as "{name}".
  std::vector<std::string> segments;
};

struct RouteMatch {
  enum class Kind {
    kFound,             // `route` and `path_params` are set.
    kFallback,          // No pattern matched; a GET/HEAD fallback handler is set.
    kNotFound,          // No pattern matched the path.
    kMethodNotAllowed,  // Some pattern matched the path, not with this verb; see `allow`.
    kBadPath,           // The path is not a valid percent-encoded absolute path.
  };
  Kind kind = Kind::kNotFound;
  const Route* route = nullptr;
  KeyValues path_params;
  // For kMethodNotAllowed: the verbs the path supports, "GET, HEAD, POST".
  std::string allow;
};

class Router {
 public:
  // Adds a route. Throws CheckError for a malformed pattern (not starting with '/', an empty or
  // unterminated "{}" parameter, a parameter mixed with text in one segment, duplicate parameter
  // names) or a duplicate {verb, pattern}: these are programming errors found at start-up.
  void Add(HttpVerb verb, std::string_view pattern, Handler handler);
  // As Add, for a handler that may block (store writes, folder removal): the transport runs
  // it on its blocking pool.
  void AddBlocking(HttpVerb verb, std::string_view pattern, Handler handler);
  void AddStreaming(HttpVerb verb, std::string_view pattern, StreamingHandler handler);

  // Answers GET and HEAD requests whose path matches no pattern.
  void SetFallback(Handler handler);
  const Handler& fallback() const { return fallback_; }

  // Matches a raw (percent-encoded) path without query string.
  RouteMatch Match(HttpVerb verb, std::string_view raw_path) const;

  const std::vector<std::unique_ptr<Route>>& routes() const { return routes_; }

 private:
  void AddHandler(HttpVerb verb, std::string_view pattern, Handler handler, bool blocking);
  void AddRoute(std::unique_ptr<Route> route);

  // unique_ptr keeps Route addresses stable for RouteMatch::route.
  std::vector<std::unique_ptr<Route>> routes_;
  Handler fallback_;
};

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_HTTP_ROUTER_H_
