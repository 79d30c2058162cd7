#include "server/api/api.h"

#include <nlohmann/json.hpp>

namespace reconduit::server {

void AddHealthRoutes(Router* router, ApiServices* services) {
  (void)services;
  // Liveness only: answers as long as the I/O loop runs. Readiness checks (database reachable,
  // disk not full) belong here once the JobStore exists.
  router->Add(HttpVerb::get, "/healthz", [](RequestContext&) {
    Response response = Response::Json({{"status", "ok"}});
    response.SetHeader("Cache-Control", "no-store");
    return response;
  });
}

}  // namespace reconduit::server
