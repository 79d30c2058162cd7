// The API layer: thin handlers that parse, validate, call a service and map the result to a
// response (STYLE.md E). Each group of routes lives in its own file and registers itself with
// an AddXxxRoutes function; AddApiRoutes wires them all and is what main.cc calls.
//
//   health.cc     GET /healthz
//   jobs.cc       POST /api/v1/jobs (the upload itself is upload.cc), GET /api/v1/jobs,
//                 GET /api/v1/jobs/{id}, .../events, .../cancel, .../restart, DELETE
//   artifacts.cc  GET /api/v1/jobs/{id}/result.zip, .../files, .../files/{name...}
//   service.cc    GET /api/v1/options, GET /metrics
//
// Adding a route group: write server/api/foo.cc with `void AddFooRoutes(Router*,
// ApiServices*)`, declare it below, call it from AddApiRoutes (api.cc) and add foo.cc to
// reconduit_server_api in server/CMakeLists.txt.
#ifndef RECONDUIT_SERVER_API_API_H_
#define RECONDUIT_SERVER_API_API_H_

#include "server/http/http_metrics.h"
#include "server/http/router.h"

#include "store/data_layout.h"
#include "store/job_store.h"
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <memory>

namespace reconduit::server {

// The upload limits (all configurable, see main.cc). The largest body is the transport's
// HttpServerOptions::max_upload_bytes; `max_upload_bytes` here repeats it for zip extraction.
struct UploadLimits {
  // Largest request body and largest total a zip upload may extract to, in bytes.
  std::uint64_t max_upload_bytes = std::uint64_t{4} << 30;
  // Photos (image parts or zip entries) per job, >= 1.
  int max_photos = 1000;
  // Largest width * height of a photo, read from its header before decoding; larger photos
  // are rejected (listed with the reason).
  std::int64_t max_pixels = 100'000'000;
  // Largest single photo in bytes.
  std::int64_t max_photo_bytes = std::int64_t{256} << 20;
  // Uploads in progress at once, >= 1; more are answered 429 with Retry-After.
  int max_concurrent_uploads = 8;
  // Queued jobs, >= 1; a new upload is answered 503 with Retry-After when this many wait.
  std::int64_t max_queued_jobs = 1000;
};

// Counters for GET /metrics. Thread-safe.
struct UploadCounters {
  // Request body bytes received by the upload route.
  std::atomic<std::uint64_t> bytes_total{0};
  // Uploads that created a job, and uploads refused for any reason after they started.
  std::atomic<std::uint64_t> accepted_total{0};
  std::atomic<std::uint64_t> refused_total{0};
  // Uploads being received right now.
  std::atomic<int> in_progress{0};
};

// The long-lived services the handlers use, owned by main() and outliving the HTTP server
// (like servertech-chat's shared_state). Handlers run on several I/O threads at once, so every
// member must be thread-safe or immutable once the server runs.
struct ApiServices {
  // Root of the data folder (jobs/<id>/..., tmp/, the database); exists and is writable.
  std::filesystem::path data_dir;
  // Seconds in Retry-After when a limit is reached.
  int retry_after_seconds = 5;
  // The job store; not owned. May be null only in servers that register no job routes.
  JobStore* store = nullptr;
  UploadLimits limits;
  UploadCounters uploads;
  // The transport's response counters (HttpServerOptions::metrics), for /metrics; may be null.
  std::shared_ptr<HttpMetrics> http_metrics;

  DataLayout layout() const { return DataLayout(data_dir); }
};

// GET /healthz -> 200 {"status":"ok"}. Public even when a bearer token is configured.
void AddHealthRoutes(Router* router, ApiServices* services);
// The job routes (jobs.cc) and the upload (upload.cc).
void AddJobRoutes(Router* router, ApiServices* services);
// Result downloads (artifacts.cc).
void AddArtifactRoutes(Router* router, ApiServices* services);
// GET /api/v1/options and GET /metrics (service.cc).
void AddServiceRoutes(Router* router, ApiServices* services);

// Every API route of the server. Does not take ownership of `services`.
void AddApiRoutes(Router* router, ApiServices* services);

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_API_API_H_
