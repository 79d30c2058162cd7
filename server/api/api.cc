#include "server/api/api.h"

namespace reconduit::server {

void AddApiRoutes(Router* router, ApiServices* services) {
  AddHealthRoutes(router, services);
  AddJobRoutes(router, services);
  AddArtifactRoutes(router, services);
  AddServiceRoutes(router, services);
}

}  // namespace reconduit::server
