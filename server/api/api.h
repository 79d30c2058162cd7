// The API layer: thin handlers that parse, validate, call a service and map the result to a
// response (STYLE.md E). Each group of routes lives in its own file (health.cc; jobs.cc,
// artifacts.cc, ... as they are written) and registers itself with an AddXxxRoutes function;
// AddApiRoutes wires them all and is what main.cc calls.
//
// Adding a route group:
//   1. server/api/jobs.cc: `void AddJobRoutes(Router* router, ApiServices* services)` with
//      router->AddStreaming(HttpVerb::post, "/api/v1/jobs", ...) for the upload and
//      router->Add(HttpVerb::get, "/api/v1/jobs/{id}", ...) for the rest;
//   2. declare it below and call it from AddApiRoutes (api.cc);
//   3. add jobs.cc to reconduit_server_api in server/CMakeLists.txt.
#ifndef RECONDUIT_SERVER_API_API_H_
#define RECONDUIT_SERVER_API_API_H_

#include "server/http/router.h"

#include <filesystem>

namespace reconduit::server {

// The long-lived services the handlers use, owned by main() and outliving the HTTP server
// (like servertech-chat's shared_state). Handlers run on several I/O threads at once, so every
// member must be thread-safe or immutable.
struct ApiServices {
  // Root of the data folder (jobs/<id>/..., the database); exists and is writable.
  std::filesystem::path data_dir;
  // Seconds in Retry-After when a limit is reached.
  int retry_after_seconds = 5;
};

// GET /healthz -> 200 {"status":"ok"}. Public even when a bearer token is configured.
void AddHealthRoutes(Router* router, ApiServices* services);

// Every API route of the server. Does not take ownership of `services`.
void AddApiRoutes(Router* router, ApiServices* services);

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_API_API_H_
