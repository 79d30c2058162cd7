// What a route handler knows about the request it answers.
//
// Built by the transport after the request header has been read and routed; handlers receive it
// by reference and never see Beast types. Path parameters and query parameters are already
// percent-decoded. For ordinary routes `body` holds the whole request body (bounded by
// HttpServerOptions::max_body_bytes); for streaming routes it is empty and the body goes to the
// route's BodySink instead (see router.h).
#ifndef RECONDUIT_SERVER_HTTP_REQUEST_CONTEXT_H_
#define RECONDUIT_SERVER_HTTP_REQUEST_CONTEXT_H_

#include "server/http/url.h"

#include <boost/beast/http/verb.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace reconduit::server {

using HttpVerb = boost::beast::http::verb;

struct RequestContext {
  HttpVerb method = HttpVerb::get;
  // The method as sent ("GET"); useful when `method` is HttpVerb::unknown.
  std::string method_string;
  // The request target as sent ("/api/v1/jobs?limit=10").
  std::string target;
  // The path part of the target, still percent-encoded ("/api/v1/jobs").
  std::string path;
  // Decoded query parameters in order ("limit" -> "10").
  KeyValues query;
  // Decoded values of the route pattern's {name} segments.
  KeyValues path_params;
  // Request headers in order, names as sent.
  KeyValues headers;
  // The client's IP address ("127.0.0.1", "::1").
  std::string remote_address;
  // The id sent back in X-Request-Id and written to the access log.
  std::string request_id;
  // Content-Length when the client sent one.
  std::optional<std::uint64_t> content_length;
  // The whole body, for non-streaming routes.
  std::string body;

  // The first header called `name` (case-insensitive), or nullopt.
  std::optional<std::string_view> Header(std::string_view name) const;
  // The first query parameter called `name` (case-sensitive), or nullopt.
  std::optional<std::string_view> Query(std::string_view name) const;
  // The path parameter `name`; empty when the route has no such parameter.
  std::string_view PathParam(std::string_view name) const;
};

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_HTTP_REQUEST_CONTEXT_H_
