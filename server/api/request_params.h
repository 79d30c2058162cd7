// Small helpers shared by the handlers: integer query parameters and the {id} path parameter.
#ifndef RECONDUIT_SERVER_API_REQUEST_PARAMS_H_
#define RECONDUIT_SERVER_API_REQUEST_PARAMS_H_

#include "core/util/status.h"
#include "server/api/api.h"
#include "server/http/request_context.h"
#include "server/http/response.h"

#include <cstdint>
#include <string_view>

namespace reconduit::server {

// A decimal integer in [min, max]; kInvalidArgument naming `name` otherwise
// ("query parameter `limit` must be an integer in [1, 1000], got \"x\"").
Result<std::int64_t> ParseInteger(std::string_view text,
                                  std::string_view name,
                                  std::int64_t min,
                                  std::int64_t max);

// The query parameter `name` parsed with ParseInteger, or `fallback` when it is absent.
Result<std::int64_t> IntegerParam(const RequestContext& context,
                                  std::string_view name,
                                  std::int64_t fallback,
                                  std::int64_t min,
                                  std::int64_t max);

// 404 {"error":{"code":"not_found","message":"no job \"<id>\""}}.
Response JobNotFoundResponse(std::string_view id);

// Wraps `handler(ApiServices*, RequestContext&, std::string_view id)` into a route handler that
// answers 404 for a path {id} that is not a well-formed job id (32 lower-case hex digits)
// before the store is asked.
template <class JobHandler>
auto WithJobId(ApiServices* services, JobHandler handler) {
  return [services, handler](RequestContext& context) -> Response {
    const std::string_view id = context.PathParam("id");
    if (!IsValidJobId(id)) return JobNotFoundResponse(id);
    return handler(services, context, id);
  };
}

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_API_REQUEST_PARAMS_H_
