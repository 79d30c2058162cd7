#include "server/api/api.h"

namespace reconduit::server {

void AddApiRoutes(Router* router, ApiServices* services) { AddHealthRoutes(router, services); }

}  // namespace reconduit::server
